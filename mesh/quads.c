/* quads.c - the triangles of the polygonizer (steps 3 and 5 of doc/mesh.md), after
 * every block has its vertices (mesh.c).
 *
 * First the face candidates are confirmed (a face crossed twice by one component on
 * both sides gets its two face vertices); then every crossing edge becomes a quad over
 * the component vertices of its four cells, split along the better diagonal, or a
 * polygon fanned from a face vertex.  Each block makes the quads of the edges it owns.
 */
#include "config.h"

#include "alloc.h"
#include "mesh_internal.h"
#include "vec3.h"

#include <math.h>
#include <string.h>

/* A split whose smaller triangle has at most this fraction of the other split's area
 * is treated as degenerate (no zero-area triangles). */
#define QUAD_MIN_AREA 1e-9

/* The block holding cell C (global padded index) and the cell's index in it; NULL
 * when the block was not processed. */
static mblock *cell_block(const mesher *M, const long C[3], int *cell)
{
    if (C[0] < 0 || C[1] < 0 || C[2] < 0 || C[0] >= M->G[0] || C[1] >= M->G[1] || C[2] >= M->G[2])
        return NULL;
    mblock *B = mesh_block_find(M, mesh_block_key(M, C[0] / MESH_BLOCK, C[1] / MESH_BLOCK,
                                                  C[2] / MESH_BLOCK));
    if (!B || !B->cs) return NULL;
    *cell = mesh_cell_index((int)(C[0] % MESH_BLOCK), (int)(C[1] % MESH_BLOCK),
                            (int)(C[2] % MESH_BLOCK));
    return B;
}

/* Keep the face candidates of mesh_block_contour whose cell across the face has its
 * component cross the face twice as well (only then would the mesh edge be made four
 * times), dropping the other candidates' vertices.  Serial and in block order: the
 * vertex numbering stays independent of the thread count. */
void mesh_resolve_faces(mesher *M)
{
    for (size_t b = 0; b < M->nblocks; b++) {
        mblock *B = M->blocks[b];
        uint32_t keep = 0;
        for (uint32_t q = 0; q < B->nfaces; q++) {
            int cell = B->fkey[q] / 3, a = B->fkey[q] % 3, ocell;
            long C[3] = { (long)B->b[0] * MESH_BLOCK + cell % MESH_BLOCK,
                          (long)B->b[1] * MESH_BLOCK + (cell / MESH_BLOCK) % MESH_BLOCK,
                          (long)B->b[2] * MESH_BLOCK + cell / (MESH_BLOCK * MESH_BLOCK) };
            C[a]--;
            const mblock *O = cell_block(M, C, &ocell);
            if (!O || !((M->table.dupface[O->cs[ocell]] >> (2 * a + 1)) & 1)) continue;
            if (keep != q) {
                size_t from = B->nverts + 2 * (size_t)q, to = B->nverts + 2 * (size_t)keep;
                memmove(&B->vpos[3 * to], &B->vpos[3 * from], 6 * sizeof *B->vpos);
                memmove(&B->vnrm[3 * to], &B->vnrm[3 * from], 6 * sizeof *B->vnrm);
                memmove(&B->vfg[4 * to], &B->vfg[4 * from], 8 * sizeof *B->vfg);
                memmove(&B->vrank[to], &B->vrank[from], 2);
                B->fkey[keep] = B->fkey[q];
            }
            keep++;
        }
        B->nfaces = keep;
    }
}

/* ---- looking up the cells around an edge ------------------------------------------ */

/* The quads of block B only reach cells in B and its 7 lower neighbours: looked up
 * once per block (below[dx + 2 dy + 4 dz] is the block at B - (dx, dy, dz)), not once
 * per cell. */
typedef struct nbhood {
    const mblock *B;
    mblock *below[8];
} nbhood;

static void nbhood_init(const mesher *M, mblock *B, nbhood *h)
{
    h->B = B;
    for (int c = 0; c < 8; c++) {
        long bx = B->b[0] - (c & 1), by = B->b[1] - ((c >> 1) & 1), bz = B->b[2] - (c >> 2);
        h->below[c] = bx < 0 || by < 0 || bz < 0 ? NULL
                                                 : mesh_block_find(M, mesh_block_key(M, bx, by, bz));
    }
}

static mblock *cell_block_nb(const mesher *M, const nbhood *h, const long C[3], int *cell)
{
    if (C[0] < 0 || C[1] < 0 || C[2] < 0 || C[0] >= M->G[0] || C[1] >= M->G[1] || C[2] >= M->G[2])
        return NULL;
    long d[3];
    for (int c = 0; c < 3; c++) {
        d[c] = h->B->b[c] - C[c] / MESH_BLOCK;
        if (d[c] < 0 || d[c] > 1) return cell_block(M, C, cell);
    }
    mblock *B = h->below[d[0] + 2 * d[1] + 4 * d[2]];
    if (!B || !B->cs) return NULL;
    *cell = mesh_cell_index((int)(C[0] % MESH_BLOCK), (int)(C[1] % MESH_BLOCK),
                            (int)(C[2] % MESH_BLOCK));
    return B;
}

/* What the diagonal choice needs of a quad's vertex. */
typedef struct qcorner {
    const double *pos, *fg;   /* position; f - iso and gradient there */
    int rank;
} qcorner;

/* Cell C (global padded index) -> vertex of the component containing edge e, and the
 * cell's configuration. */
static int cell_vertex(const mesher *M, const nbhood *h, const long C[3], int e, uint32_t *v,
                       qcorner *q, int *cs)
{
    int cell;
    mblock *B = cell_block_nb(M, h, C, &cell);
    if (!B || B->vbase[cell] == MESH_NO_VERTEX) return -1;
    *cs = B->cs[cell];
    uint8_t cyc = M->table.cycle[B->cs[cell]][e];
    if (cyc == 0xFF) return -1;
    uint32_t local = (uint32_t)B->vbase[cell] + cyc;
    *v = (uint32_t)(B->vglobal + local);
    q->pos = &B->vpos[3 * local];
    q->fg = &B->vfg[4 * local];
    q->rank = B->vrank[local];
    return 0;
}

/* Global index of the vertex of segment seg on the face across axis ax below cell C
 * (the face's high-side cell), or -1 when mesh_resolve_faces() did not confirm it. */
static int face_vertex(const mesher *M, const nbhood *h, const long C[3], int ax, int seg)
{
    int cell;
    mblock *B = cell_block_nb(M, h, C, &cell);
    if (!B || seg < 0 || seg > 1) return -1;
    uint16_t key = (uint16_t)(3 * cell + ax);
    size_t lo = 0, hi = B->nfaces;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (B->fkey[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    if (lo == B->nfaces || B->fkey[lo] != key) return -1;
    return (int)(B->vglobal + B->nverts + 2 * lo + (size_t)seg);
}

/* ---- one block's triangles -------------------------------------------------------- */

/* The triangles a block is making. */
typedef struct quad_ctx {
    mesher *M;
    mblock *B;
    nbhood nh;
    long base[3];             /* global padded index of the block's first cell */
    uint32_t *tri;            /* 3 * cap indices */
    size_t cap, nt;
} quad_ctx;

/* The quad of one crossing edge: its axis and the four cells around it. */
typedef struct equad {
    int a, o1, o2;            /* the edge's axis and the two others */
    int in0;                  /* the edge's lower corner is inside */
    long C[4][3];             /* the cells, counter-clockwise around +a (see ring) */
    uint32_t v[4];            /* their component vertices */
    qcorner q[4];
    int cs[4];                /* their configurations (case and joined faces) */
} equad;

/* (d1, d2) counter-clockwise around +a when (o1, o2, a) is right-handed: cell r is the
 * owner cell minus d1 along o1 and d2 along o2. */
static const int ring[4][2] = { { 1, 1 }, { 0, 1 }, { 0, 0 }, { 1, 0 } };

/* Room for at least 8 more triangles. 0, or -1 when out of memory. */
static int grow_tris(quad_ctx *c)
{
    size_t nc = c->cap + c->cap / 2 + 16;
    uint32_t *nt = frep_realloc(c->tri, 3 * nc * sizeof *nt);
    if (!nt) return -1;
    c->tri = nt;
    c->cap = nc;
    return 0;
}

static double tri_area2(const double *a, const double *b, const double *c)
{
    double u[3], w[3], n[3];
    vec3_sub(b, a, u);
    vec3_sub(c, a, w);
    vec3_cross(u, w, n);
    return vec3_len(n);
}

/* f - iso at the midpoint of a and b estimated by the cubic Hermite interpolant of the
 * values and gradients at the ends: (fa + fb) / 2 + (ga - gb) . (b - a) / 8. */
static double hermite_mid(const qcorner *a, const qcorner *b)
{
    double d = 0;
    for (int c = 0; c < 3; c++) d += (a->fg[c + 1] - b->fg[c + 1]) * (b->pos[c] - a->pos[c]);
    return 0.5 * (a->fg[0] + b->fg[0]) + d / 8;
}

/* Triangles of polygon p[0..n-1] (ring order, reversed when flip), where mid[t] marks
 * the face vertices: fanned from the first face vertex, so every new diagonal ends at
 * a vertex only the two polygons of one face segment share and no mesh edge is made
 * twice.  Returns 0 or -1 (out of memory). */
static int quad_fan(quad_ctx *c, const uint32_t *p, const uint8_t *mid, int n, int flip)
{
    uint32_t r[8];
    int s = -1;
    for (int t = 0; t < n; t++) {
        int from = flip ? (n - t) % n : t;
        r[t] = p[from];
        if (mid[from] && s < 0) s = t;
    }
    if (s < 0) s = 0;
    if (c->nt + 8 > c->cap && grow_tris(c) != 0) return -1;
    for (int t = 1; t + 1 < n; t++) {
        uint32_t *o = &c->tri[3 * c->nt++];
        o[0] = r[s];
        o[1] = r[(s + t) % n];
        o[2] = r[(s + t + 1) % n];
    }
    return 0;
}

/* The four cells around the edge of axis a at owner cell L (local) and their
 * component vertices; -1 when one has none (its block was not contoured). */
static int quad_cells(const quad_ctx *c, const int L[3], equad *E)
{
    for (int r = 0; r < 4; r++) {
        for (int k = 0; k < 3; k++) E->C[r][k] = c->base[k] + L[k];
        E->C[r][E->o1] -= ring[r][0];
        E->C[r][E->o2] -= ring[r][1];
        int e = 4 * E->a + ring[r][0] + 2 * ring[r][1];
        if (cell_vertex(c->M, &c->nh, E->C[r], e, &E->v[r], &E->q[r], &E->cs[r]) != 0)
            return -1;
    }
    return 0;
}

/* The quad's ring with, between two cells whose common face is crossed twice on both
 * sides, that face's vertex of the edge's segment (face_candidates in mesh.c).
 * Returns the number of face vertices added; a missing one marks the block failed. */
static int quad_polygon(quad_ctx *c, const int L[3], const equad *E, uint32_t poly[8],
                        uint8_t pmid[8], int *npoly)
{
    const mesher *M = c->M;
    int nmid = 0;
    *npoly = 0;
    for (int r = 0; r < 4; r++) {
        pmid[*npoly] = 0;
        poly[(*npoly)++] = E->v[r];
        int r2 = (r + 1) & 3, ax = E->C[r][E->o1] != E->C[r2][E->o1] ? E->o1 : E->o2;
        int hi = E->C[r][ax] > E->C[r2][ax] ? r : r2, lo = hi == r ? r2 : r;
        if (!((M->table.dupface[E->cs[lo]] >> (2 * ax + 1)) & 1) ||
            !((M->table.dupface[E->cs[hi]] >> (2 * ax)) & 1))
            continue;
        /* the segment of the edge's end it cuts off: the inside end, or the outside
         * end where the face joins its inside corners; segments are numbered by that
         * corner's coordinate along the face's first axis u */
        int a = E->a, u = a < 3 - a - ax ? a : 3 - a - ax;
        int cut_hi = E->in0 == mesh_face_joined(E->cs[hi], ax, 0);
        long pin = c->base[u] + L[u] + (u == a ? cut_hi : 0);
        int mv = face_vertex(M, &c->nh, E->C[hi], ax, (int)(pin - E->C[hi][u]));
        if (mv < 0) {
            c->B->failed = 1;
            continue;
        }
        pmid[*npoly] = 1;
        poly[(*npoly)++] = (uint32_t)mv;
        nmid++;
    }
    return nmid;
}

/* Triangle a, b, c faces the quad's way: its normal's component along the edge's
 * axis ax has the sign out (+1: the edge's outside end is its upper end).  The
 * vertices lie in the four cells around the edge, so seen along the edge they lie
 * in four quadrants in ring order; a triangle facing the other way folds over its
 * neighbour (a sharp crease can put three feature vertices of one quad on a convex
 * curve, and the chord between two of them behind the third). */
static int tri_faces(const double *a, const double *b, const double *c, int ax, int out)
{
    double u[3], w[3], n[3];
    vec3_sub(b, a, u);
    vec3_sub(c, a, w);
    vec3_cross(u, w, n);
    return n[ax] * out > 0;
}

/* Split along v0-v2 (1) or v1-v3 (0)?  The diagonal joining two feature vertices (QEF
 * rank >= 2) when only one does, since it lies on the sharp edge (with three, the one
 * ending at the middle one, since the sides hold the edge); otherwise the one
 * whose midpoint is closer to the surface by the Hermite estimate; never a split
 * making a zero-area triangle, nor one with a triangle facing backwards (along the
 * edge's axis ax, outside direction out) when the other split has none. */
static int quad_diagonal(const qcorner q[4], int ax, int out)
{
    int f02 = q[0].rank >= 2 && q[2].rank >= 2;
    int f13 = q[1].rank >= 2 && q[3].rank >= 2;
    /* three feature vertices: the crease runs along the quad's sides through the
     * middle one, and the chord joining the other two would cut across it, leaving a
     * sliver that folds (tests/models/segment_box.hf -b 1.2 at -g 27, 50 and 122):
     * the diagonal ends at the middle one */
    if ((q[0].rank >= 2) + (q[1].rank >= 2) + (q[2].rank >= 2) + (q[3].rank >= 2) == 3) {
        f02 = !f02;
        f13 = !f13;
    }
    int use02;
    if (f02 != f13) {
        use02 = f02;
    } else {
        double e02 = fabs(hermite_mid(&q[0], &q[2]));
        double e13 = fabs(hermite_mid(&q[1], &q[3]));
        use02 = !(e13 < e02) || isnan(e13);
        if (isnan(e02) && !isnan(e13)) use02 = 0;
    }
    double a02 = fmin(tri_area2(q[0].pos, q[1].pos, q[2].pos),
                      tri_area2(q[0].pos, q[2].pos, q[3].pos));
    double a13 = fmin(tri_area2(q[0].pos, q[1].pos, q[3].pos),
                      tri_area2(q[1].pos, q[2].pos, q[3].pos));
    double amax = fmax(a02, a13);
    if (use02 && a02 <= QUAD_MIN_AREA * amax) use02 = 0;
    else if (!use02 && a13 <= QUAD_MIN_AREA * amax) use02 = 1;
    int ok02 = tri_faces(q[0].pos, q[1].pos, q[2].pos, ax, out) &&
               tri_faces(q[0].pos, q[2].pos, q[3].pos, ax, out) && a02 > QUAD_MIN_AREA * amax;
    int ok13 = tri_faces(q[0].pos, q[1].pos, q[3].pos, ax, out) &&
               tri_faces(q[1].pos, q[2].pos, q[3].pos, ax, out) && a13 > QUAD_MIN_AREA * amax;
    if (ok02 != ok13) use02 = ok02;
    return use02;
}

/* The two triangles of a plain quad (ring order, reversed when flip). */
static int quad_split(quad_ctx *c, equad *E, int flip)
{
    uint32_t *v = E->v;
    if (flip) {
        uint32_t t = v[1]; v[1] = v[3]; v[3] = t;
        qcorner tq = E->q[1]; E->q[1] = E->q[3]; E->q[3] = tq;
    }
    int use02 = quad_diagonal(E->q, E->a, E->in0 ? 1 : -1);
    if (c->nt + 2 > c->cap && grow_tris(c) != 0) return -1;
    uint32_t *t = &c->tri[3 * c->nt];
    c->nt += 2;
    if (use02) {
        t[0] = v[0]; t[1] = v[1]; t[2] = v[2];
        t[3] = v[0]; t[4] = v[2]; t[5] = v[3];
    } else {
        t[0] = v[0]; t[1] = v[1]; t[2] = v[3];
        t[3] = v[1]; t[4] = v[2]; t[5] = v[3];
    }
    return 0;
}

/* The triangles of the crossing edge of axis a owned by cell L (local) of case cs.
 * 0, or -1 when out of memory. */
static int edge_quad(quad_ctx *c, const int L[3], int cs, int a)
{
    equad E;
    E.a = a;
    E.in0 = cs & 1;
    mesh_edge_other_axes(a, &E.o1, &E.o2);
    if (quad_cells(c, L, &E) != 0) {
        c->B->failed = 1;
        return 0;
    }
    /* (o1, o2, a) is right-handed except for a == 1 (x, z, y); the quad must face
     * away from the inside end of the edge. */
    int flip = (a == 1) ^ (E.in0 == 0);
    uint32_t poly[8];
    uint8_t pmid[8];
    int npoly;
    if (quad_polygon(c, L, &E, poly, pmid, &npoly) > 0) return quad_fan(c, poly, pmid, npoly, flip);
    return quad_split(c, &E, flip);
}

/* Two triangles per crossing edge the block owns (more only for the rare polygons):
 * sized up front, as over-allocation here was a good part of the peak memory. */
static size_t quads_capacity(const mblock *B)
{
    size_t cap = 0;
    for (int cell = 0; cell < MESH_BLOCK_CELLS; cell++) {
        int cs = B->cs[cell];
        cap += (size_t)(((cs ^ (cs >> 1)) & 1) + ((cs ^ (cs >> 2)) & 1) + ((cs ^ (cs >> 4)) & 1));
    }
    return 2 * cap;
}

/* Quads of the crossing edges whose owner cell (the cell at the edge's lower corner)
 * lies in block B. */
int mesh_block_quads(mesher *M, mmem *mem, mblock *B)
{
    size_t cap = quads_capacity(B);
    B->ntri = 0;
    B->tri = NULL;
    if (cap == 0) return 0;
    if (mem->tricap < cap) {
        uint32_t *t = frep_realloc(mem->tri, 3 * cap * sizeof *t);
        if (!t) return -1;
        mem->tri = t;
        mem->tricap = cap;
    }
    quad_ctx c = { .M = M, .B = B, .cap = mem->tricap, .tri = mem->tri };
    nbhood_init(M, B, &c.nh);
    for (int k = 0; k < 3; k++) c.base[k] = (long)B->b[k] * MESH_BLOCK;
    int rc = 0;
    for (int k = 0; k < MESH_BLOCK && rc == 0; k++)
        for (int j = 0; j < MESH_BLOCK && rc == 0; j++)
            for (int i = 0; i < MESH_BLOCK && rc == 0; i++) {
                int cs = B->cs[mesh_cell_index(i, j, k)];
                if (cs == 0 || cs == 255) continue;
                const int L[3] = { i, j, k };
                for (int a = 0; a < 3 && rc == 0; a++)
                    if ((cs & 1) != ((cs >> (1 << a)) & 1)) rc = edge_quad(&c, L, cs, a);
            }
    /* grow_tris may have moved the buffer */
    mem->tri = c.tri;
    mem->tricap = c.cap;
    if (rc != 0) return -1;
    B->tri = mesh_pool_alloc(&mem->pool[MESH_POOL_TRI], 3 * c.nt * sizeof *B->tri);
    if (!B->tri) return -1;
    memcpy(B->tri, c.tri, 3 * c.nt * sizeof *B->tri);
    B->ntri = c.nt;
    return 0;
}
