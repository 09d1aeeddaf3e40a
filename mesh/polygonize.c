/* polygonize.c - mesh_polygonize (mesh.h): the polygonizer's driver, the steps of
 * doc/mesh.md ("Method") in order.
 *
 * Octree pruning finds the blocks (octree.c); each block is contoured (mesh.c), in
 * parallel, blocks with crossings towards unlisted ones bringing them in; the faces
 * crossed twice are confirmed and the quads made (quads.c); the blocks' vertices and
 * triangles are assembled in key order, so the mesh does not depend on the thread
 * count; vertices left off the surface are settled onto it (settle.c).  The result
 * goes to geom/meshio.c, mesh/sample.c or mesh/render.c.
 */
#include "config.h"

#include "alloc.h"
#include "mesh_internal.h"
#include "util.h"

#include <math.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* Working memory a contoured block is charged for: the block, its cases and vertex
 * indices (3 bytes a cell) and 48 bytes a vertex (position, normal). */
#define POLY_BLOCK_BYTES (sizeof(mblock) + MESH_BLOCK_CELLS * 3)
#define POLY_VERTEX_BYTES 48
/* Shares of the progress fraction: contouring, then the quads. */
#define POLY_CONTOUR_SHARE 0.9
#define POLY_QUADS_SHARE 0.1

void mesh_options_init(mesh_options *o)
{
    memset(o, 0, sizeof *o);
    for (int c = 0; c < 3; c++) {
        o->box[c] = -10;
        o->box[c + 3] = 10;
    }
    o->grid = 30;
    o->iso = 0;
}

/* Refuse a grid outside 1..MESH_MAX_GRID, an empty or non-finite box, a non-finite
 * iso level. */
static int check_options(const mesh_options *o, frep_error *e)
{
    for (int c = 0; c < 3; c++) {
        int g = mesh_options_cells(o, c);
        if (g < 1 || g > MESH_MAX_GRID)
            return frep_error_set(e, FREP_EINPUT, "grid of %d cells along %c is outside 1..%d", g,
                                  "xyz"[c], MESH_MAX_GRID);
    }
    for (int c = 0; c < 3; c++) {
        if (!isfinite(o->box[c]) || !isfinite(o->box[c + 3]) || !(o->box[c + 3] > o->box[c]))
            return frep_error_set(e, FREP_EINPUT, "empty or invalid box: %c from %g to %g",
                                  "xyz"[c], o->box[c], o->box[c + 3]);
    }
    if (!isfinite(o->iso)) return frep_error_set(e, FREP_EINPUT, "the iso level must be a finite number");
    return 0;
}

/* ---- the blocks' memory (mesh_internal.h) ---- */

/* A slab's pages are faulted in POLY_FAULT_STEP bytes at a time ahead of its use
 * (frep_prefault): one system call instead of 16 page faults, and at most one step
 * faulted and unused at the end of each pool. */
#define POLY_FAULT_STEP ((uintptr_t)1 << 16)

struct mslab {
    mslab *next;
    size_t used, cap;         /* bytes of data */
    char *ready;              /* data before it is faulted in */
    max_align_t data[];
};

void *mesh_pool_alloc(mpool *p, size_t n)
{
    const size_t align = _Alignof(max_align_t);
    n = (n + align - 1) / align * align;
    mslab *s = p->slabs;
    if (!s || s->cap - s->used < n) {
        size_t cap = MESH_SLAB_BYTES - sizeof *s;
        if (n > cap) cap = n;
        s = frep_malloc(sizeof *s + cap);
        if (!s) return NULL;
        s->next = p->slabs;
        s->used = 0;
        s->cap = cap;
        s->ready = (char *)s->data;
        p->slabs = s;
    }
    char *a = (char *)s->data + s->used;
    s->used += n;
    if (a + n > s->ready) {
        uintptr_t to = ((uintptr_t)(a + n) + POLY_FAULT_STEP - 1) & ~(POLY_FAULT_STEP - 1);
        char *end = (char *)s->data + s->cap;
        if (to > (uintptr_t)end) to = (uintptr_t)end;
        frep_prefault(s->ready, (size_t)(to - (uintptr_t)s->ready));
        s->ready = (char *)to;
    }
    return a;
}

static void pool_free(mpool *p)
{
    while (p->slabs) {
        mslab *next = p->slabs->next;
        frep_free(p->slabs);
        p->slabs = next;
    }
}

void mesh_pools_free(const mesher *M, int kind)
{
    for (int t = 0; t < M->nthreads; t++) pool_free(&M->mems[t].pool[kind]);
}

/* The run's grid (padded by one cell on every side), its blocks per axis, threads,
 * and per-thread field states and buffers.  0, or -1 when out of memory. */
static int mesher_init(mesher *M, const mesh_field *f, const mesh_options *o, mesh_stats *st)
{
    M->f = f;
    M->o = o;
    mesh_cell_table_build(&M->table);
    M->nbk = 0;
    for (int c = 0; c < 3; c++) {
        M->g[c] = mesh_options_cells(o, c);
        M->G[c] = M->g[c] + 2;
        M->nb[c] = (M->G[c] + MESH_BLOCK - 1) / MESH_BLOCK;
        if (M->nb[c] > M->nbk) M->nbk = M->nb[c];
        M->h[c] = (o->box[c + 3] - o->box[c]) / M->g[c];
    }
    M->nthreads = frep_threads(o->nthreads);
    if (M->nthreads > FREP_PAR_MAX_THREADS) M->nthreads = FREP_PAR_MAX_THREADS;
    st->blocks_total = (size_t)M->nb[0] * (size_t)M->nb[1] * (size_t)M->nb[2];
    M->ts = frep_calloc((size_t)M->nthreads, sizeof *M->ts);
    M->works = frep_calloc((size_t)M->nthreads, sizeof *M->works);
    M->mems = frep_calloc((size_t)M->nthreads, sizeof *M->mems);
    if (!M->ts || !M->works || !M->mems) return -1;
    for (int t = 0; t < M->nthreads; t++) {
        M->ts[t] = f->thread_new(f->ctx);
        M->works[t] = mesh_work_new();
        if (!M->ts[t] || !M->works[t]) return -1;
    }
    return 0;
}

/* Free the run; the threads' evaluation counts go to st. */
static void mesher_free(mesher *M, mesh_stats *st)
{
    if (M->blocks)
        for (size_t i = 0; i < M->nblocks; i++) mesh_block_free(M->blocks[i]);
    frep_free(M->blocks);
    if (M->ts)
        for (int t = 0; t < M->nthreads; t++)
            if (M->ts[t]) M->f->thread_free(M->f->ctx, M->ts[t]);
    frep_free(M->ts);
    if (M->works)
        for (int t = 0; t < M->nthreads; t++) mesh_work_free(M->works[t], st);
    frep_free(M->works);
    if (M->mems) {
        for (int kind = 0; kind < MESH_POOLS; kind++) mesh_pools_free(M, kind);
        for (int t = 0; t < M->nthreads; t++) frep_free(M->mems[t].tri);
    }
    frep_free(M->mems);
    frep_free(M);
}

/* One contour round's blocks, shared by its threads. */
typedef struct contour_job {
    mesher *M;
    mblock **todo;
    size_t total;             /* blocks of the run, for the progress */
    _Atomic size_t done;      /* blocks contoured so far */
    _Atomic int nomem, bad;
} contour_job;

static void contour_chunk(void *ctx, int t, long i0, long i1)
{
    contour_job *J = ctx;
    mesher *M = J->M;
    const mesh_options *o = M->o;
    for (long i = i0; i < i1; i++) {
        if (frep_cancelled(o->interrupt)) continue;
        int rc = mesh_block_contour(M, M->works[t], &M->mems[t], M->ts[t], J->todo[i]);
        if (rc == FREP_ENOMEM) atomic_store(&J->nomem, 1);
        else if (rc != 0) atomic_store(&J->bad, 1);
        size_t d = atomic_fetch_add(&J->done, 1);
        if (t == 0 && o->progress)
            o->progress(o->progress_user, POLY_CONTOUR_SHARE * (double)d / (double)(J->total + 1));
    }
}

/* Contour blocks [first, nblocks) in parallel; *done counts the blocks contoured so
 * far, for the progress. */
static int contour_round(mesher *M, size_t first, size_t *done, frep_error *e)
{
    const mesh_options *o = M->o;
    long n = (long)(M->nblocks - first);
    contour_job J = { M, M->blocks + first, M->nblocks, *done, 0, 0 };
    frep_par_for(mesh_threads_for(M, (double)n * MESH_CONTOUR_POINTS, (size_t)n), n, 1,
                 contour_chunk, &J);
    *done = atomic_load(&J.done);
    if (frep_cancelled(o->interrupt)) return frep_error_set(e, FREP_ECANCEL, "interrupted");
    if (atomic_load(&J.nomem) || atomic_load(&J.bad))
        return frep_error_set(e, atomic_load(&J.nomem) ? FREP_ENOMEM : FREP_EINPUT,
                              "out of memory or evaluation failure while meshing");
    return 0;
}

/* Charge blocks [first, old) to the working memory; refuse more than
 * MESH_MAX_WORK_BYTES. */
static int charge_memory(mesher *M, size_t first, size_t old, frep_error *e)
{
    for (size_t i = first; i < old; i++)
        M->bytes += POLY_BLOCK_BYTES + POLY_VERTEX_BYTES * (size_t)M->blocks[i]->nverts;
    if (M->bytes > MESH_MAX_WORK_BYTES)
        return frep_error_set(e, FREP_ELIMIT, "the mesh needs more than %zu MiB of working "
                              "memory; use a smaller -g", MESH_MAX_WORK_BYTES >> 20);
    return 0;
}

/* Step 2 with the closure of step 6: contour the listed blocks; blocks found to have
 * crossings towards a block not yet listed (the interval test is sound, but NaN and
 * rounding are not its business) bring that block in, until the surface is closed.
 * Leaves the blocks sorted. */
static int contour_blocks(mesher *M, frep_error *e)
{
    size_t first = 0, done = 0;
    while (first < M->nblocks) {
        size_t old = M->nblocks;
        if (contour_round(M, first, &done, e) != 0 || charge_memory(M, first, old, e) != 0)
            return -1;
        if (mesh_add_needed_blocks(M, first, old) != 0) return frep_error_nomem(e);
        first = old;
    }
    if (M->nblocks > 1) qsort(M->blocks, M->nblocks, sizeof *M->blocks, mesh_block_cmp);
    return 0;
}

/* Sum the blocks' counts into st, drop the blocks without vertices and number the
 * vertices in block order (cell vertices, then face vertices).  Returns the number
 * of vertices. */
static size_t number_vertices(mesher *M, mesh_stats *st)
{
    size_t nkeep = 0, nverts = 0;
    uint32_t inside = 0, real_cross = 0;
    for (size_t i = 0; i < M->nblocks; i++) {
        mblock *B = M->blocks[i];
        st->points_nan += B->nan_points;
        st->cells_split += B->split_cells;
        inside += B->inside_corners > 0;
        real_cross += B->real_crossings > 0;
        if (B->virtual_crossings) st->touches_box = 1;
        if (B->nverts == 0) {
            mesh_block_free(B);
            continue;
        }
        B->vglobal = nverts;
        nverts += B->nverts + 2 * (size_t)B->nfaces;
        st->face_vertices += 2 * (size_t)B->nfaces;
        M->blocks[nkeep++] = B;
    }
    M->nblocks = nkeep;
    st->full = inside > 0 && real_cross == 0;
    return nverts;
}

/* The quads of the blocks, shared by the threads of step 5. */
typedef struct quads_job {
    mesher *M;
    long n;
    _Atomic int failed;
} quads_job;

static void quads_chunk(void *ctx, int t, long i0, long i1)
{
    quads_job *J = ctx;
    mesher *M = J->M;
    const mesh_options *o = M->o;
    for (long i = i0; i < i1; i++) {
        if (frep_cancelled(o->interrupt)) continue;
        if (mesh_block_quads(M, &M->mems[t], M->blocks[i]) != 0) atomic_store(&J->failed, 1);
        if (t == 0 && o->progress)
            o->progress(o->progress_user, POLY_CONTOUR_SHARE +
                                              POLY_QUADS_SHARE * (double)i / (double)(J->n + 1));
    }
}

/* Step 5: every block's quads, in parallel. */
static int make_quads(mesher *M, frep_error *e)
{
    const mesh_options *o = M->o;
    long n = (long)M->nblocks;
    quads_job J = { M, n, 0 };
    frep_par_for(mesh_threads_for(M, (double)n * MESH_QUADS_POINTS, (size_t)n), n, 1,
                 quads_chunk, &J);
    if (frep_cancelled(o->interrupt)) return frep_error_set(e, FREP_ECANCEL, "interrupted");
    if (atomic_load(&J.failed))
        return frep_error_set(e, FREP_ENOMEM, "out of memory or evaluation failure while meshing");
    return 0;
}

/* Assembly copies the blocks' arrays into the mesh one kind at a time, each kind's
 * pools freed as soon as it is copied, so that at the peak the mesh is held once plus
 * one kind, not twice.  The blocks keep their vfg for settling (settle.c).  Every
 * block's place in the mesh is known before the copy (vglobal, tglobal), so the
 * threads copy the blocks in any order into the mesh's arrays, sized once, and the
 * mesh does not depend on the thread count. */

/* A copy below this many bytes stays on one thread: ~0.1 ms of copying and page
 * faults, while starting a helper costs 10-100 us. */
#define POLY_PAR_MIN_BYTES ((size_t)1 << 20)
/* Blocks handed to a thread at a time (a block holds ~100 vertices). */
#define POLY_COPY_CHUNK 16

/* One kind of the blocks' arrays copied into the mesh's, shared by the threads. */
typedef struct gather_job {
    const mesher *M;
    int kind;                 /* MESH_POOL_TRI, _POS or _NRM */
    void *all;                /* the mesh's array of that kind */
} gather_job;

/* Copy blocks [i0, i1)'s arrays of the job's kind to their places. */
static void gather_chunk(void *ctx, int t, long i0, long i1)
{
    (void)t;
    gather_job *J = ctx;
    for (long i = i0; i < i1; i++) {
        mblock *B = J->M->blocks[i];
        if (J->kind == MESH_POOL_TRI) {
            uint32_t *all = J->all;
            if (B->ntri) memcpy(all + 3 * B->tglobal, B->tri, 3 * B->ntri * sizeof *all);
            B->tri = NULL;
            continue;
        }
        double *all = J->all, **a = J->kind == MESH_POOL_POS ? &B->vpos : &B->vnrm;
        memcpy(all + 3 * B->vglobal, *a, 3 * (B->nverts + 2 * (size_t)B->nfaces) * sizeof *all);
        *a = NULL;
    }
}

/* The blocks' arrays of one kind into a new array of n elements of `size` bytes, on
 * as many threads as its size deserves; then the kind's pools are freed.  NULL when
 * out of memory. */
static void *gather(const mesher *M, int kind, size_t n, size_t size)
{
    gather_job J = { M, kind, frep_malloc((n + 1) * size) };
    if (!J.all) return NULL;
    frep_prefault(J.all, n * size);
    long nb = (long)M->nblocks;
    int nt = n * size < POLY_PAR_MIN_BYTES || nb < 2 * POLY_COPY_CHUNK ? 1 : M->nthreads;
    frep_par_for(nt, nb, POLY_COPY_CHUNK, gather_chunk, &J);
    mesh_pools_free(M, kind);
    return J.all;
}

/* The blocks' vertices and triangles, in block order, into out.  The arrays only
 * the quads read go first, then each kind as it is gathered. */
static int assemble(const mesher *M, size_t nverts, frep_mesh *out, frep_error *e)
{
    size_t ntris = 0;
    int holes = 0;
    for (size_t i = 0; i < M->nblocks; i++) {
        M->blocks[i]->tglobal = ntris;
        ntris += M->blocks[i]->ntri;
        holes |= M->blocks[i]->failed;
    }
    if (holes) return frep_error_set(e, FREP_EINTERNAL, "internal error: a surface cell was not evaluated");
    if (ntris > MESH_MAX_TRIANGLES)
        return frep_error_set(e, FREP_ELIMIT, "the mesh has more than %zu triangles; use a smaller -g",
                              (size_t)MESH_MAX_TRIANGLES);
    for (size_t i = 0; i < M->nblocks; i++) {
        mblock *B = M->blocks[i];
        B->cs = B->vbase = B->fkey = NULL;
    }
    mesh_pools_free(M, MESH_POOL_CELLS);
    out->nverts = nverts;
    out->ntris = ntris;
    int ok = (out->tri = gather(M, MESH_POOL_TRI, 3 * ntris, sizeof *out->tri)) != NULL;
    ok = ok && (out->v = gather(M, MESH_POOL_POS, 3 * nverts, sizeof *out->v)) != NULL;
    ok = ok && (out->n = gather(M, MESH_POOL_NRM, 3 * nverts, sizeof *out->n)) != NULL;
    if (!ok) {
        mesh_free(out);
        return frep_error_nomem(e);
    }
    return 0;
}

/* The wall time since *t into st's clock of stage k; *t becomes now. */
static void clock_stage(mesh_stats *st, int k, double *t)
{
    double now = frep_now_seconds();
    st->stage_seconds[k] += now - *t;
    *t = now;
}

/* Steps 1 to 6 on an initialized run. */
static int polygonize(mesher *M, mesh_stats *st, frep_mesh *out, frep_error *e)
{
    double t = frep_now_seconds();
    if (mesh_find_blocks(M, st, e) != 0) return -1;
    clock_stage(st, MESH_STAGE_OCTREE, &t);
    if (contour_blocks(M, e) != 0) return -1;
    st->blocks = M->nblocks;
    mesh_resolve_faces(M);
    size_t nverts = number_vertices(M, st);
    clock_stage(st, MESH_STAGE_CONTOUR, &t);
    if (nverts >= UINT32_MAX)
        return frep_error_set(e, FREP_ELIMIT, "the mesh has more than 2^32 vertices; use a smaller -g");
    if (make_quads(M, e) != 0) return -1;
    clock_stage(st, MESH_STAGE_QUADS, &t);
    if (assemble(M, nverts, out, e) != 0) return -1;
    clock_stage(st, MESH_STAGE_ASSEMBLY, &t);
    if (!M->o->no_projection) {
        int rc = mesh_settle_vertices(M, out, st);
        clock_stage(st, MESH_STAGE_SETTLE, &t);
        if (rc != 0) {
            mesh_free(out);
            return rc == FREP_ENOMEM ? frep_error_nomem(e)
                                     : frep_error_set(e, FREP_EINPUT, "evaluation failure while meshing");
        }
    }
    if (M->o->progress) M->o->progress(M->o->progress_user, 1.0);
    return 0;
}

int mesh_polygonize(const mesh_field *f, const mesh_options *o, frep_mesh *out,
                    mesh_stats *stats, frep_error *e)
{
    double t_start = frep_now_seconds();
    mesh_stats st_local;
    mesh_stats *st = stats ? stats : &st_local;
    memset(st, 0, sizeof *st);
    memset(out, 0, sizeof *out);
    if (check_options(o, e) != 0) return -1;
    mesher *M = frep_calloc(1, sizeof *M);
    if (!M) return frep_error_nomem(e);
    int status = mesher_init(M, f, o, st) != 0 ? frep_error_nomem(e) : polygonize(M, st, out, e);
    mesher_free(M, st);
    st->seconds = frep_now_seconds() - t_start;
    return status;
}
