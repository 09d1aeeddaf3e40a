/* octree.c - which blocks of MESH_BLOCK^3 cells the polygonizer contours (step 1 of
 * doc/mesh.md, and the closure of step 6).
 *
 * An octree over the blocks of the padded grid asks the field's interval callback for
 * an enclosure over each node and drops the nodes proven empty or full; the surviving
 * leaves become the run's sorted block list.  Blocks whose contouring found crossings
 * towards an unlisted block bring it in (mesh_add_needed_blocks).
 */
#include "config.h"

#include "alloc.h"
#include "mesh_internal.h"

#include <math.h>
#include <stdlib.h>

/* Initial capacity of the block list; it doubles from there. */
#define OCTREE_FIRST_BLOCKS 1024
/* Initial capacity of an octree level; it doubles from there. */
#define OCTREE_FIRST_NODES 64

uint64_t mesh_block_key(const mesher *M, long bx, long by, long bz)
{
    return ((uint64_t)bz * (uint64_t)M->nbk + (uint64_t)by) * (uint64_t)M->nbk + (uint64_t)bx;
}

/* The block with this key among the first n (sorted) blocks, or NULL. */
static mblock *block_find_in(const mesher *M, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (M->blocks[mid]->key < key) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && M->blocks[lo]->key == key ? M->blocks[lo] : NULL;
}

mblock *mesh_block_find(const mesher *M, uint64_t key)
{
    return block_find_in(M, M->nblocks, key);
}

int mesh_block_cmp(const void *a, const void *b)
{
    const mblock *x = *(mblock *const *)a, *y = *(mblock *const *)b;
    return x->key < y->key ? -1 : x->key > y->key;
}

void mesh_block_free(mblock *B)
{
    frep_free(B);
}

int mesh_block_add(mesher *M, long bx, long by, long bz)
{
    if (M->nblocks == M->capblocks) {
        size_t cap = M->capblocks ? 2 * M->capblocks : OCTREE_FIRST_BLOCKS;
        mblock **nbk = frep_realloc(M->blocks, cap * sizeof *nbk);
        if (!nbk) return -1;
        M->blocks = nbk;
        M->capblocks = cap;
    }
    mblock *B = frep_calloc(1, sizeof *B);
    if (!B) return -1;
    B->b[0] = (int)bx;
    B->b[1] = (int)by;
    B->b[2] = (int)bz;
    B->key = mesh_block_key(M, bx, by, bz);
    M->blocks[M->nblocks++] = B;
    return 0;
}

/* ---- the octree ------------------------------------------------------------------- */

/* A node: the cube of s^3 blocks from block (x, y, z). */
typedef struct onode {
    int x, y, z, s;
} onode;

/* One level of the octree. */
typedef struct olevel {
    onode *node;
    size_t n, cap;
} olevel;

/* The box of node nd's cells (clipped to the padded grid); *pad: it reaches the
 * padding, whose outer corners count as outside whatever the field says. */
static void node_box(const mesher *M, const onode *nd, double box[6], int *pad)
{
    long c0[3] = { (long)nd->x * MESH_BLOCK, (long)nd->y * MESH_BLOCK, (long)nd->z * MESH_BLOCK };
    long c1[3];
    *pad = 0;
    for (int c = 0; c < 3; c++) {
        c1[c] = c0[c] + (long)nd->s * MESH_BLOCK;
        if (c1[c] > M->G[c]) c1[c] = M->G[c];
        if (c0[c] == 0 || c1[c] == M->G[c]) *pad = 1;
        box[c] = mesh_coord(M, c, c0[c]);
        box[c + 3] = mesh_coord(M, c, c1[c]);
    }
}

/* May node nd hold surface (tested on thread t)? No when the enclosure is below iso
 * (empty) or at least iso (full) away from the padding. */
static int node_keep(const mesher *M, int t, const onode *nd)
{
    double box[6];
    int pad;
    node_box(M, nd, box, &pad);
    if (!M->f->interval) return 1;
    double lo = -INFINITY, hi = INFINITY;
    if (M->f->interval(M->f->ctx, M->ts[t], box, &lo, &hi) != 0) return 1;
    if (hi < M->o->iso) return 0;
    return !(lo >= M->o->iso && !pad);
}

/* Append node ch to level L; 0, or -1 when out of memory. */
static int level_push(olevel *L, onode ch)
{
    if (L->n == L->cap) {
        size_t cap = L->cap ? 2 * L->cap : OCTREE_FIRST_NODES;
        onode *nn = frep_realloc(L->node, cap * sizeof *nn);
        if (!nn) return -1;
        L->node = nn;
        L->cap = cap;
    }
    L->node[L->n++] = ch;
    return 0;
}

/* The kept nodes of cur, in order: a leaf (one block) joins the block list, a larger
 * node puts its children inside the grid on next.  0, or -1 when out of memory. */
static int level_split(mesher *M, const olevel *cur, const uint8_t *keep, olevel *next)
{
    for (size_t i = 0; i < cur->n; i++) {
        if (!keep[i]) continue;
        const onode *nd = &cur->node[i];
        if (nd->s == 1) {
            if (mesh_block_add(M, nd->x, nd->y, nd->z) != 0) return -1;
            continue;
        }
        int hs = nd->s / 2;
        for (int c = 0; c < 8; c++) {
            onode ch = { nd->x + (c & 1) * hs, nd->y + ((c >> 1) & 1) * hs,
                         nd->z + ((c >> 2) & 1) * hs, hs };
            if (ch.x >= M->nb[0] || ch.y >= M->nb[1] || ch.z >= M->nb[2]) continue;
            if (level_push(next, ch) != 0) return -1;
        }
    }
    return 0;
}

/* The nodes of one level tested by the threads of level_step. */
typedef struct level_job {
    const mesher *M;
    const onode *node;
    uint8_t *keep;
} level_job;

static void level_chunk(void *ctx, int t, long i0, long i1)
{
    level_job *J = ctx;
    for (long i = i0; i < i1; i++)
        J->keep[i] = frep_cancelled(J->M->o->interrupt) ? 0
                                                        : (uint8_t)node_keep(J->M, t, &J->node[i]);
}

/* Nodes handed to a thread at a time: an interval evaluation is short. */
#define OCTREE_CHUNK 8

/* Test one level in parallel and make the next one; 0, or -1 when out of memory. */
static int level_step(mesher *M, mesh_stats *st, const olevel *cur, olevel *next)
{
    uint8_t *keep = frep_malloc(cur->n);
    if (!keep) return -1;
    st->octree_nodes += cur->n;
    long n = (long)cur->n;
    level_job J = { M, cur->node, keep };
    size_t chunks = (cur->n + OCTREE_CHUNK - 1) / OCTREE_CHUNK;
    frep_par_for(mesh_threads_for(M, (double)n * MESH_INTERVAL_POINTS, chunks), n, OCTREE_CHUNK,
                 level_chunk, &J);
    int rc = frep_cancelled(M->o->interrupt) ? 1 : level_split(M, cur, keep, next);
    frep_free(keep);
    return rc;
}

int mesh_find_blocks(mesher *M, mesh_stats *st, frep_error *e)
{
    int S = 1;
    while (S < M->nbk) S *= 2;
    olevel cur = { NULL, 0, 0 }, next = { NULL, 0, 0 };
    onode root = { 0, 0, 0, S };
    int rc = level_push(&cur, root);
    while (rc == 0 && cur.n > 0) {
        rc = level_step(M, st, &cur, &next);
        frep_free(cur.node);
        cur = next;
        next = (olevel){ NULL, 0, 0 };
    }
    frep_free(cur.node);
    frep_free(next.node);
    if (rc > 0) return frep_error_set(e, FREP_ECANCEL, "interrupted");
    if (rc != 0) return frep_error_set(e, FREP_ENOMEM, "out of memory building the octree");
    if (M->nblocks > 1) qsort(M->blocks, M->nblocks, sizeof *M->blocks, mesh_block_cmp);
    return 0;
}

/* ---- closure ---------------------------------------------------------------------- */

/* Is the block with this key missing from the list: neither among the first old
 * (sorted) blocks nor among those appended since? */
static int block_missing(const mesher *M, size_t old, uint64_t key)
{
    if (block_find_in(M, old, key)) return 0;
    for (size_t q = old; q < M->nblocks; q++)
        if (M->blocks[q]->key == key) return 0;
    return 1;
}

int mesh_add_needed_blocks(mesher *M, size_t first, size_t old)
{
    /* blocks [0, old) are contoured: sort them for lookups; new ones go after */
    if (old > 1) qsort(M->blocks, old, sizeof *M->blocks, mesh_block_cmp);
    for (size_t i = first; i < old; i++) {
        const mblock *B = M->blocks[i];
        for (int bit = 0; bit < 27; bit++) {
            if (!(B->need & (1u << bit))) continue;
            long nx = B->b[0] + bit % 3 - 1, ny = B->b[1] + (bit / 3) % 3 - 1,
                 nz = B->b[2] + bit / 9 - 1;
            if (nx < 0 || ny < 0 || nz < 0 || nx >= M->nb[0] || ny >= M->nb[1] || nz >= M->nb[2])
                continue;
            if (!block_missing(M, old, mesh_block_key(M, nx, ny, nz))) continue;
            if (mesh_block_add(M, nx, ny, nz) != 0) return -1;
        }
    }
    return 0;
}
