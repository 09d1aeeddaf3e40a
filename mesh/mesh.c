/* mesh.c - dual contouring of one block of MESH_BLOCK^3 cells (steps 2-4 of
 * doc/mesh.md): the block's corner values, its crossing edges located by regula falsi
 * with normals from the analytic gradient, each cell's crossings split into surface
 * components (cycles, see below) and one vertex per component by a QEF (truncated
 * pseudo-inverse, mass-point bias, clamped to the cell), so sharp CSG edges and corners
 * survive.  Blocks come from octree.c; their quads are made by quads.c; the run is
 * driven by polygonize.c.
 *
 * Manifoldness: a cell's crossing edges are paired on each face (an ambiguous face,
 * two inside corners on a diagonal, joins or separates them by the field at its
 * centre: face_decisions), which only depends on the face, so both cells sharing a
 * face agree; following the pairs gives cycles, one vertex each.  Every mesh edge then joins the vertices of two cells across
 * one segment of their common face, and every vertex's quads follow its cycle around:
 * one closed fan.  The one exception, a face whose two segments belong to one
 * component on both sides (a tunnel thinner than a cell), would make the same mesh
 * edge twice; such faces get a vertex per segment (face_candidates here,
 * mesh_resolve_faces in quads.c), so the mesh is a closed 2-manifold for any field.
 * The grid is padded with a layer of cells whose outer corners count as outside, so a
 * solid cut by the box is closed by caps on the box.  A block reads only its own
 * corners and the field, so blocks are contoured independently, in any order.
 */
#include "config.h"

#include "alloc.h"
#include "linalg.h"
#include "mesh_internal.h"
#include "vec3.h"

#include <math.h>
#include <string.h>

/* Regula falsi (Illinois) steps per crossing at most: converges superlinearly; 8 steps
 * put crossings of smooth fields far below 1e-6 cell.  A crossing stops earlier when
 * its bracket is narrower than MESH_ROOT_TOL (fraction of the edge) or it hit the
 * level exactly, so near-linear fields (planes) cost one or two evaluations. */
#define MESH_ROOT_STEPS 8
#define MESH_ROOT_TOL 1e-5
/* A crossing also stops when the secant slope over its bracket puts the last point
 * within this fraction of the edge from the root: the Newton step along the edge that
 * the gradient at the final point pays for (step 3) then takes a smooth field's
 * crossing to about the square of that. */
#define MESH_ROOT_FTOL 1e-2
/* A crossing stopped by MESH_ROOT_FTOL whose Newton step then leaves its bracket, the
 * field flatter at the final point than over the bracket (root_flat), has no sound
 * estimate of its error, and is bisected this many more times, to 1/256 of its
 * bracket.  A wall 0.05 thick: its R-intersection is flat past its end
 * (the slab's quadratic under 6e-4), the first secant guess landed on the flat side
 * 0.12 cell from the end and the stop took it, the wall's corner was lost and a
 * vertex left 1.05 cell off the surface (tests/models/sharp/near.hf at -g 55). */
#define MESH_ROOT_BISECT 8
/* ... unless the final point is within this many cells of the surface by its own value
 * and gradient: then a sheet runs along the edge, the point is on the surface for
 * every later step, and where the root lies along the edge is ill-conditioned.  The
 * x-edges 0.02 cell above the wall's top face crossing the cylinder that pokes through
 * it: bisected to the cylinder, their vertices folded (near.hf at -g 83, 8
 * self-intersecting pairs). */
#define MESH_ROOT_NEAR 0.1
/* QEF eigenvalues below this fraction of the largest are dropped (truncated
 * pseudo-inverse): near-parallel normals must not throw the vertex out of its cell. */
#define MESH_QEF_CUTOFF 0.05
/* A corner solution of the QEF (rank 3) at most this fraction of a cell outside its
 * cell, in a cell with a corner exactly on the level, is clamped into the cell rather
 * than given up for a lower rank: a part's corner whose faces lie on grid planes is on
 * the faces of the cells around it, where rounding puts it on either side, and the
 * lower rank's mass point was up to 3/4 cell off the surface (tests/models/sharp/near.hf
 * at -g 32).  Off for the sampler's mesh (mesh_options.no_projection), which stays as
 * before.  Other edge and corner solutions outside the cell are clamped only when they
 * fit (MESH_QEF_FIT): clamped unchecked, two cells' vertices met on their common face
 * and folded triangles over each other (tests/models/segment_box.hf at -g 64, -b 1.2). */
#define MESH_QEF_REACH 0.05
/* An edge or corner solution of the QEF (rank 2 or 3) outside its cell, or within
 * MESH_CLAMP of its faces, is clamped into the cell and kept, rather than given up for
 * a lower rank, when the crease is the cell's own: the cell's crossings do not all lie
 * on one face of the cell, and every crossing's tangent plane passes within this
 * fraction of a cell of the clamped point.  A sharp edge on a grid plane (within
 * rounding: examples/bracket.hf's x = 1 at -g 26 and 104) lies on the faces of the
 * cells beside it, and a crease just past a cell's face leaves it only a sliver of
 * both faces; the lower rank's mass point was up to half a cell off the surface
 * (bracket.hf had 2 to 76 vertices over 0.1 cell at -g 22, 26, 52, 78, 104, 130, 149,
 * 154 and 156, gear.hf 8 at -g 70, near.hf 1 at -g 40), or its fan folded over its
 * neighbours' (segment_cylinder.hf 6 self-intersecting pairs at -g 54, 134 and 142,
 * twist.hf 8 at -g 42, segment_box.hf 4 at -g 141).  Crossings all on one face are a
 * flat face on a grid plane: the edge their normals suggest (the gradient at a kink on
 * the rim) is the neighbours', and kept here it moved the face vertices of a cube on
 * grid planes onto its rim (tests/cli.sh, -g 4,4,8).  The tangent planes keep out a
 * point the crossings of two sheets pull together (tests/models/sharp/near.hf at -g 20:
 * a block's end on a grid plane beside a wall's edge, 0.31 cell off).  A clamped point
 * that misses a plane can still lie on the surface; the field decides for a mass point
 * left off it (clamped_on_surface), to the same MESH_QEF_FIT. */
#define MESH_QEF_FIT 0.1
/* Vertices stay this fraction of a cell inside their cell, so that vertices of
 * different cells never coincide (no zero-area triangles). */
#define MESH_CLAMP 1e-4
/* Vertices of a block at most: 4 surface components per cell, plus 2 vertices on each
 * of a cell's 3 low faces when one component crosses that face twice (see
 * face_candidates). */
#define MESH_BLOCK_VMAX (10 * MESH_BLOCK_CELLS)
/* A cell vertex farther than this fraction of a cell from the surface (|f - iso| /
 * |grad f|, the grid scaled to unit cubes) after the QEF is projected onto it
 * (project_vertices): Newton steps along the gradient, at most MESH_PROJECT_STEPS of
 * them (one batch of gradients each), each kept only when it brings the vertex
 * closer.  The steps stay MESH_PROJECT_MARGIN of a cell inside the cell's faces:
 * projected to the faces, vertices of neighbouring cells folded quads over each other
 * (tests/models/segment_cone.hf at -g 32, examples/twist.hf at -g 128). */
#define MESH_PROJECT_TOL 0.1
/* A vertex the QEF left at the mass point (rank 0: no edge, corner or flat patch of the
 * crossings fit in the cell) is projected when farther than this, and its Newton steps
 * go on until it is this near: the mass point of a cell holding two creases beside a
 * corner outside it is off the surface, and its first steps along the R-function's
 * gradient, which leans between the planes there, stopped 0.065 cell outside a face,
 * under MESH_PROJECT_TOL, where its fan met its neighbours'
 * (tests/models/segment_box.hf at -g 42 and 90, -b 1.2).  Projecting every vertex that
 * near folded the gyroid's quads (bench/bench_gyroid.hf at -g 53); mass points
 * projected to 0.02 cell folded segment_box.hf at -g 30. */
#define MESH_PROJECT_TOL_MASS 0.05
/* A Newton step of the projection is kept only where the surface reached faces the
 * way of the component's crossings (their mean normal): another sheet of the cell, as
 * of a part a hair's breadth away, faces the other way.  When the crossings' normals
 * all agree (their mean at least MESH_PROJECT_ONE_WAY long: one sheet), the surface
 * reached may face away from them down to the cosine MESH_PROJECT_FACING, the other
 * side of a crease: a hole's wall meeting a spherical cap at 111 degrees, its
 * crossings a hair below the rim all with the wall's normal, left a flat patch's vertex
 * 0.2 cell above the rim, whose steps reached the cap (examples/csg.hf at -g 117, 16
 * vertices; tests/models/sharp/near.hf at -g 134, 2 vertices and 6 pairs).  Crossings
 * of two sheets meeting at an acute wedge keep the strict rule: their vertex projected
 * onto one of them folded (bench/bench_gyroid.hf in a sphere, -g 128 -b 1.6: 12
 * self-intersecting pairs instead of 3 vertices 0.3 cell off). */
#define MESH_PROJECT_FACING (-0.5)
#define MESH_PROJECT_ONE_WAY 0.95
#define MESH_PROJECT_STEPS 4
#define MESH_PROJECT_MARGIN 0.05

/* ---- cell topology table (the layout is in mesh_internal.h) ----------------------- */

static int edge_start(int e)
{
    int a = e / 4, o1, o2;
    mesh_edge_other_axes(a, &o1, &o2);
    return ((e & 1) << o1) | (((e >> 1) & 1) << o2);
}

static int edge_end(int e) { return edge_start(e) | (1 << (e / 4)); }

/* Which of the 12 edges of case cs cross the surface (one end inside). */
static void case_crossings(int cs, int cross[12])
{
    for (int e = 0; e < 12; e++)
        cross[e] = ((cs >> edge_start(e)) & 1) != ((cs >> edge_end(e)) & 1);
}

/* The crossing edges of the face of side s across axis a, in edge order; their number. */
static int face_crossings(const int cross[12], int a, int s, int fe[4])
{
    int nf = 0;
    for (int e = 0; e < 12; e++) {
        int ea = e / 4;
        if (ea == a) continue;
        int o1, o2;
        mesh_edge_other_axes(ea, &o1, &o2);
        int coord = o1 == a ? (e & 1) : ((e >> 1) & 1);
        if (coord == s && cross[e]) fe[nf++] = e;
    }
    return nf;
}

static void pair_edges(int partner[12][2], int np[12], int e0, int e1)
{
    partner[e0][np[e0]++] = e1;
    partner[e1][np[e1]++] = e0;
}

/* Pair the crossing edges of configuration cf (case cf & 255) on each face: the two of
 * a simple face; on an ambiguous face (four), the two around each inside corner, so
 * that the inside corners are separated, or, when the face joins them, the two around
 * each outside corner. */
static void pair_faces(int cf, const int cross[12], int partner[12][2], int np[12])
{
    for (int e = 0; e < 12; e++) np[e] = 0;
    for (int a = 0; a < 3; a++)
        for (int s = 0; s < 2; s++) {
            int fe[4], nf = face_crossings(cross, a, s, fe);
            if (nf == 2) pair_edges(partner, np, fe[0], fe[1]);
            if (nf != 4) continue;
            int cut = !mesh_face_joined(cf, a, s);  /* the side of the corners cut off */
            for (int c = 0; c < 8; c++) {
                if (((c >> a) & 1) != s || ((cf >> c) & 1) != cut) continue;
                int pair[2], k = 0;
                for (int i = 0; i < 4; i++)
                    if (edge_start(fe[i]) == c || edge_end(fe[i]) == c) pair[k++] = fe[i];
                if (k == 2) pair_edges(partner, np, pair[0], pair[1]);
            }
        }
}

/* Follow the pairs from each crossing edge not yet reached: one cycle, one surface
 * component, numbered in order of their first edge.  Returns the number of cycles. */
static uint8_t trace_cycles(cell_table *t, int cf, const int cross[12],
                            const int partner[12][2], const int np[12])
{
    uint8_t nc = 0;
    for (int e = 0; e < 12; e++) t->cycle[cf][e] = 0xFF;
    for (int e = 0; e < 12; e++) {
        if (!cross[e] || t->cycle[cf][e] != 0xFF) continue;
        int prev = -1, cur = e;
        while (cur >= 0 && t->cycle[cf][cur] == 0xFF) {
            t->cycle[cf][cur] = nc;
            int next = partner[cur][0] != prev ? partner[cur][0] : partner[cur][1];
            if (np[cur] < 2) next = -1;
            prev = cur;
            cur = next;
        }
        nc++;
    }
    return nc;
}

/* Bit 2a + s: face 2a + s of case cs is ambiguous (its inside corners on a diagonal). */
static int ambiguous_faces(int cs)
{
    int amb = 0;
    for (int a = 0; a < 3; a++)
        for (int s = 0; s < 2; s++) {
            int fc[4], n = 0;
            for (int c = 0; c < 8; c++)
                if (((c >> a) & 1) == s) fc[n++] = (cs >> c) & 1;
            /* fc in corner order: fc[0], fc[3] and fc[1], fc[2] are the diagonals */
            if (fc[0] == fc[3] && fc[1] == fc[2] && fc[0] != fc[1]) amb |= 1 << (2 * a + s);
        }
    return amb;
}

/* Bit 2a + s: both segments of ambiguous face 2a + s belong to one component. */
static uint8_t dup_faces(const cell_table *t, int cf, const int cross[12])
{
    uint8_t dup = 0;
    for (int a = 0; a < 3; a++)
        for (int s = 0; s < 2; s++) {
            int fe[4], nf = face_crossings(cross, a, s, fe), same = 1;
            for (int i = 1; i < nf; i++)
                if (t->cycle[cf][fe[i]] != t->cycle[cf][fe[0]]) same = 0;
            if (nf == 4 && same) dup |= (uint8_t)(1u << (2 * a + s));
        }
    return dup;
}

void mesh_cell_table_build(cell_table *t)
{
    for (int cs = 0; cs < 256; cs++) {
        int cross[12], amb = ambiguous_faces(cs);
        case_crossings(cs, cross);
        /* every subset of the ambiguous faces joined */
        for (int j = amb;; j = (j - 1) & amb) {
            int cf = cs | j << MESH_FACE_SHIFT, partner[12][2], np[12];
            pair_faces(cf, cross, partner, np);
            t->ncycles[cf] = trace_cycles(t, cf, cross, (const int(*)[2])partner, np);
            t->dupface[cf] = dup_faces(t, cf, cross);
            if (j == 0) break;
        }
    }
}

/* ---- small linear algebra: symmetric 3x3 eigen decomposition (cyclic Jacobi) ------ */

/* The QEF matrix is a sum of n n^T over unit normals, entries of order 1 or more: an
 * off-diagonal sum below 1e-30 is far below rounding; 24 sweeps bound the loop. */
static const linalg_jacobi_stop qef_stop = {24, 1e-30, 0, 1e-300};

/* Whether every crossing's tangent plane passes within MESH_QEF_FIT of a cell of x
 * (the distance measured on the grid scaled to unit cubes, as --check does). */
static int qef_fits(int np, const double (*p)[3], const double (*nrm)[3], const double x[3],
                    const double lo[3], const double hi[3])
{
    for (int i = 0; i < np; i++) {
        double r = 0, s = 0;
        for (int c = 0; c < 3; c++) {
            double hn = nrm[i][c] * (hi[c] - lo[c]);
            r += nrm[i][c] * (x[c] - p[i][c]);
            s += hn * hn;
        }
        if (!(r * r <= MESH_QEF_FIT * MESH_QEF_FIT * s)) return 0;
    }
    return 1;
}

/* Minimize sum (n_i . (x - p_i))^2 near the mass point, inside [lo, hi] (a corner
 * solution up to reach cells outside is clamped in, see MESH_QEF_REACH; with
 * clamp_fit, any edge or corner solution that still fits the crossings clamped, see
 * MESH_QEF_FIT). Returns the rank used: 1 on a flat patch, 2 on an edge, 3 at a corner
 * (0: the mass point); alt and alt_rank: the highest-rank solution clamped that did not
 * fit (alt_rank 0: none), for clamped_on_surface to try against the field. */
static int qef_solve(int np, const double (*p)[3], const double (*nrm)[3],
                      const double lo[3], const double hi[3], double reach, int clamp_fit,
                      double out[3], double alt[3], int *alt_rank)
{
    *alt_rank = 0;
    double m[3] = { 0, 0, 0 };
    for (int i = 0; i < np; i++)
        for (int c = 0; c < 3; c++) m[c] += p[i][c] / np;
    double A[3][3] = { { 0 } }, b[3] = { 0, 0, 0 };
    for (int i = 0; i < np; i++) {
        double d = nrm[i][0] * (p[i][0] - m[0]) + nrm[i][1] * (p[i][1] - m[1]) +
                   nrm[i][2] * (p[i][2] - m[2]);
        for (int r = 0; r < 3; r++) {
            b[r] += nrm[i][r] * d;
            for (int c = 0; c < 3; c++) A[r][c] += nrm[i][r] * nrm[i][c];
        }
    }
    double slack[3], lo_in[3], hi_in[3];
    for (int c = 0; c < 3; c++) {
        slack[c] = MESH_CLAMP * (hi[c] - lo[c]);
        lo_in[c] = lo[c] - reach * (hi[c] - lo[c]);
        hi_in[c] = hi[c] + reach * (hi[c] - lo[c]);
    }
    /* Flat patch, the common case: with u the mean normal's direction, the two lower
     * eigenvalues sum to at most sum (1 - (n_i.u)^2) (the trace is sum |n_i|^2) and
     * the largest is at least u'Au; when the first is below MESH_QEF_CUTOFF times the
     * second, the rank is 1 and u stands in for the top eigenvector (they differ by
     * less than the normals' spread): no eigen decomposition. */
    {
        double u[3] = { 0, 0, 0 }, tr = 0, lu = 0;
        for (int i = 0; i < np; i++)
            for (int c = 0; c < 3; c++) u[c] += nrm[i][c];
        lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        if (lu > 0) {
            for (int c = 0; c < 3; c++) u[c] /= lu;
            double uau = 0, ub = u[0] * b[0] + u[1] * b[1] + u[2] * b[2];
            for (int r = 0; r < 3; r++)
                for (int c = 0; c < 3; c++) uau += u[r] * A[r][c] * u[c];
            tr = A[0][0] + A[1][1] + A[2][2];
            if (uau > 0 && tr - uau <= MESH_QEF_CUTOFF * uau) {
                double x[3];
                int inside = 1;
                for (int c = 0; c < 3; c++) {
                    x[c] = m[c] + u[c] * ub / uau;
                    if (!(x[c] >= lo[c] + slack[c] && x[c] <= hi[c] - slack[c])) inside = 0;
                }
                int rank = inside;
                for (int c = 0; c < 3; c++) {
                    double y = inside ? x[c] : m[c];
                    out[c] = fmin(fmax(y, lo[c] + slack[c]), hi[c] - slack[c]);
                }
                return rank;
            }
        }
    }
    double w[3], V[3][3];
    linalg_sym3_jacobi((const double(*)[3])A, &qef_stop, w, V);
    int ord[3] = { 0, 1, 2 };
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++)
            if (w[ord[j]] > w[ord[i]]) { int t = ord[i]; ord[i] = ord[j]; ord[j] = t; }
    double wmax = w[ord[0]];
    int rank = 0;
    while (rank < 3 && wmax > 0 && w[ord[rank]] > MESH_QEF_CUTOFF * wmax) rank++;
    for (; rank >= 0; rank--) {
        double x[3] = { m[0], m[1], m[2] };
        for (int j = 0; j < rank; j++) {
            int k = ord[j];
            double coef = (V[0][k] * b[0] + V[1][k] * b[1] + V[2][k] * b[2]) / w[k];
            for (int c = 0; c < 3; c++) x[c] += coef * V[c][k];
        }
        int inside = 1;
        double y[3];  /* x clamped into the cell */
        for (int c = 0; c < 3; c++) {
            if (!(x[c] >= (rank == 3 ? lo_in[c] : lo[c]) + slack[c] &&
                  x[c] <= (rank == 3 ? hi_in[c] : hi[c]) - slack[c]))
                inside = 0;
            y[c] = fmin(fmax(x[c], lo[c] + slack[c]), hi[c] - slack[c]);
        }
        if (!inside && clamp_fit && rank >= 2) {
            inside = qef_fits(np, p, nrm, y, lo, hi);
            if (!inside && *alt_rank == 0) {
                memcpy(alt, y, sizeof y);
                *alt_rank = rank;
            }
        }
        if (inside || rank == 0) {
            memcpy(out, y, sizeof y);
            return rank;
        }
    }
    return 0;
}

/* ---- one block -------------------------------------------------------------------- */

/* Per-thread buffers for one block. */
struct mwork {
    double cx[MESH_BLOCK_CORNERS], cy[MESH_BLOCK_CORNERS], cz[MESH_BLOCK_CORNERS];
    double cf[MESH_BLOCK_CORNERS];
    uint8_t cin[MESH_BLOCK_CORNERS];
    uint32_t rows[MESH_BLOCK + 1][MESH_BLOCK + 1];  /* [k][j]: bit i is cin of (i, j, k) */
    int32_t eidx[MESH_BLOCK_EDGES];
    double px[MESH_BLOCK_EDGES], py[MESH_BLOCK_EDGES], pz[MESH_BLOCK_EDGES];
    double nx[MESH_BLOCK_EDGES], ny[MESH_BLOCK_EDGES], nz[MESH_BLOCK_EDGES];
    /* root finding: edge crossing index, bracket (t, f - iso) and last moved side */
    int32_t rid[MESH_BLOCK_EDGES];
    double t0[MESH_BLOCK_EDGES], g0[MESH_BLOCK_EDGES], t1[MESH_BLOCK_EDGES],
        g1[MESH_BLOCK_EDGES], tt[MESH_BLOCK_EDGES];
    double ax[MESH_BLOCK_EDGES], ay[MESH_BLOCK_EDGES], az[MESH_BLOCK_EDGES];
    double dx[MESH_BLOCK_EDGES], dy[MESH_BLOCK_EDGES], dz[MESH_BLOCK_EDGES];
    /* -1, 1: end moved last; 0: none yet; 2: converged; 3: stopped by MESH_ROOT_FTOL */
    int8_t side[MESH_BLOCK_EDGES];
    int32_t act[MESH_BLOCK_EDGES];   /* crossings evaluated in this step */
    double qx[MESH_BLOCK_EDGES], qy[MESH_BLOCK_EDGES], qz[MESH_BLOCK_EDGES],
        qf[MESH_BLOCK_EDGES], gx[MESH_BLOCK_EDGES], gy[MESH_BLOCK_EDGES],
        gz[MESH_BLOCK_EDGES];
    /* bit a: the ambiguous face across axis a whose lowest corner is this one joins its
     * inside corners (face_decisions) */
    uint8_t fjoin[MESH_BLOCK_CORNERS];
    /* configurations and first vertices of the cells, copied into the block when it
     * has vertices */
    uint16_t cs[MESH_BLOCK_CELLS], vbase[MESH_BLOCK_CELLS];
    /* vertices under construction */
    double vx[MESH_BLOCK_VMAX], vy[MESH_BLOCK_VMAX], vz[MESH_BLOCK_VMAX];
    double fnx[MESH_BLOCK_VMAX], fny[MESH_BLOCK_VMAX], fnz[MESH_BLOCK_VMAX];
    double vf[MESH_BLOCK_VMAX], vgx[MESH_BLOCK_VMAX], vgy[MESH_BLOCK_VMAX],
        vgz[MESH_BLOCK_VMAX];
    uint8_t vrank[MESH_BLOCK_VMAX];
    /* a mass point's edge or corner solution clamped into the cell that missed a
     * crossing's tangent plane, and its rank (0: none; see clamped_on_surface) */
    double altx[MESH_BLOCK_VMAX], alty[MESH_BLOCK_VMAX], altz[MESH_BLOCK_VMAX];
    uint8_t altrank[MESH_BLOCK_VMAX];
    uint8_t vone[MESH_BLOCK_VMAX];   /* crossings' normals agree (MESH_PROJECT_ONE_WAY) */
    uint16_t vcell[MESH_BLOCK_VMAX]; /* the cell of each cell vertex */
    /* projection batch: vertex, candidate position, its value and gradient */
    int32_t jid[MESH_BLOCK_VMAX];
    double jx[MESH_BLOCK_VMAX], jy[MESH_BLOCK_VMAX], jz[MESH_BLOCK_VMAX];
    double jf[MESH_BLOCK_VMAX], jgx[MESH_BLOCK_VMAX], jgy[MESH_BLOCK_VMAX],
        jgz[MESH_BLOCK_VMAX];
    /* face candidates: keys and their two vertices (position, mean crossing normal) */
    uint16_t fkey[3 * MESH_BLOCK_CELLS];
    double sx[6 * MESH_BLOCK_CELLS], sy[6 * MESH_BLOCK_CELLS], sz[6 * MESH_BLOCK_CELLS];
    double snx[6 * MESH_BLOCK_CELLS], sny[6 * MESH_BLOCK_CELLS], snz[6 * MESH_BLOCK_CELLS];
    size_t eval_points, grad_points;  /* work done by this thread, for mesh_stats */
};

mwork *mesh_work_new(void)
{
    mwork *W = frep_malloc(sizeof *W);
    if (W) W->eval_points = W->grad_points = 0;
    return W;
}

void mesh_work_free(mwork *W, mesh_stats *st)
{
    if (!W) return;
    st->eval_points += W->eval_points;
    st->grad_points += W->grad_points;
    frep_free(W);
}

/* A block being contoured: the stages below fill W and B in order. */
typedef struct block_ctx {
    const mesher *M;
    mwork *W;
    mmem *mem;                /* the thread's pools, for the block's arrays */
    void *ts;                 /* the thread's field state */
    mblock *B;
    const mesh_field *f;
    double iso;
    long base[3];             /* global padded index of the block's first corner */
    int focused;              /* the field is specialized to bb */
    double bb[6], sign_tol;   /* ... and keeps the sign of values of magnitude >= sign_tol */
    double cc[3][MESH_BLOCK + 1];  /* corner coordinates along each axis */
    int creal[3][MESH_BLOCK + 1];  /* ... and whether they are real grid points */
    int ncross, nroot;        /* crossing edges; those with both ends real (root found) */
    size_t nv, nf;            /* cell vertices; face candidates */
    int joined;               /* some face joins its inside corners (W->fjoin is set) */
} block_ctx;

static const int cstride[3] = { 1, MESH_BLOCK + 1, (MESH_BLOCK + 1) * (MESH_BLOCK + 1) };

static int corner_index(int i, int j, int k)
{
    return i + (MESH_BLOCK + 1) * (j + (MESH_BLOCK + 1) * k);
}

/* World coordinate of padded corner index P along axis c. */
static double corner_coord(const mesher *M, int c, long P) { return mesh_coord(M, c, P); }

static int corner_is_real(const mesher *M, int c, long P) { return P >= 1 && P <= M->G[c] - 1; }

/* A field callback's status as the block's: FREP_EINPUT when it failed. */
static int field_status(int rc) { return rc != 0 ? FREP_EINPUT : 0; }

/* Regula falsi guess for crossing r from its bracket; bisection when the values
 * cannot be used.  The ends' values never have the same sign (0 counts as inside), so
 * a secant guess outside the bracket is rounding ((t1 g0) / g0 one ulp above t1 when
 * g1 is 0): it is clamped to the bracket, not replaced by the midpoint, which threw a
 * root found exactly (a plane's, after one Illinois step) half its bracket away
 * (examples/bracket.hf at -g 256: a crossing 0.06 cell off the rib's face, a folded
 * sliver along its 45-degree edge). */
static double root_guess(const mwork *W, int r)
{
    double g0 = W->g0[r], g1 = W->g1[r], t0 = W->t0[r], t1 = W->t1[r];
    if (!(isfinite(g0) && isfinite(g1) && g0 != g1)) return 0.5 * (t0 + t1);
    double t = (t0 * g1 - t1 * g0) / (g1 - g0);
    return isnan(t) ? 0.5 * (t0 + t1) : fmin(fmax(t, t0), t1);
}

/* 0. Specialize the field to the block's box: every evaluation below lies in it. */
static int block_focus(block_ctx *c)
{
    const mesher *M = c->M;
    c->sign_tol = 0;
    c->focused = c->f->focus && c->iso == 0;
    if (!c->focused) return 0;
    mesh_block_box(M, c->B, c->bb);
    return field_status(c->f->focus(c->f->ctx, c->ts, c->bb, &c->sign_tol));
}

/* The block's corner coordinates along each axis, and which are real grid points
 * (the padding's outer corners are not: they count as outside). */
static void corner_grid(block_ctx *c)
{
    for (int k = 0; k < 3; k++)
        for (int q = 0; q <= MESH_BLOCK; q++) {
            c->cc[k][q] = corner_coord(c->M, k, c->base[k] + q);
            c->creal[k][q] = corner_is_real(c->M, k, c->base[k] + q);
        }
}

/* Corners and face centres are shared with the neighbouring blocks, which prune
 * differently: of the n batch values f at (x, y, z), those near 0, whose sign rounding
 * may decide, come from the whole program so that all blocks agree. */
static int recheck_near_level(block_ctx *c, size_t n, const double *x, const double *y,
                              const double *z, double *f)
{
    mwork *W = c->W;
    const mesh_field *fl = c->f;
    size_t nz = 0;
    for (size_t q = 0; q < n; q++)
        if (fabs(f[q]) < c->sign_tol) {
            W->rid[nz] = (int32_t)q;
            W->gx[nz] = x[q];
            W->gy[nz] = y[q];
            W->gz[nz] = z[q];
            nz++;
        }
    if (nz == 0) return 0;
    if (fl->focus(fl->ctx, c->ts, NULL, NULL) != 0 ||
        fl->eval(fl->ctx, c->ts, nz, W->gx, W->gy, W->gz, W->tt) != 0 ||
        fl->focus(fl->ctx, c->ts, c->bb, &c->sign_tol) != 0)
        return FREP_EINPUT;
    W->eval_points += nz;
    for (size_t q = 0; q < nz; q++) f[W->rid[q]] = W->tt[q];
    return 0;
}

/* 1. The values of the block's real corners, in one batch; then each corner's value
 * (NaN off the grid) and side (inside: f >= iso). */
static int corner_values(block_ctx *c)
{
    mwork *W = c->W;
    mblock *B = c->B;
    size_t nreal = 0;
    int32_t *map = W->eidx; /* reused: corner -> position in the batch */
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++)
            for (int i = 0; i <= MESH_BLOCK; i++) {
                int ci = corner_index(i, j, k);
                map[ci] = -1;
                if (c->creal[0][i] && c->creal[1][j] && c->creal[2][k]) {
                    W->cx[nreal] = c->cc[0][i];
                    W->cy[nreal] = c->cc[1][j];
                    W->cz[nreal] = c->cc[2][k];
                    map[ci] = (int32_t)nreal++;
                }
            }
    if (nreal && c->f->eval(c->f->ctx, c->ts, nreal, W->cx, W->cy, W->cz, W->qf) != 0)
        return FREP_EINPUT;
    W->eval_points += nreal;
    if (c->focused && c->sign_tol > 0) {
        int rc = recheck_near_level(c, nreal, W->cx, W->cy, W->cz, W->qf);
        if (rc) return rc;
    }
    for (int ci = 0; ci < MESH_BLOCK_CORNERS; ci++) {
        if (map[ci] < 0) {
            W->cf[ci] = NAN;
            W->cin[ci] = 0;
        } else {
            double v = W->qf[map[ci]];
            W->cf[ci] = v;
            W->cin[ci] = v >= c->iso;
            if (isnan(v)) B->nan_points++;
            if (W->cin[ci]) B->inside_corners++;
        }
    }
    return 0;
}

/* Mark the blocks holding cells around the crossing edge at corner q along axis a
 * (only edges on the block's faces have cells in other blocks): they must be
 * contoured too. */
static void mark_needed(mblock *B, const int q[3], int a)
{
    int o1, o2;
    mesh_edge_other_axes(a, &o1, &o2);
    int on_face = !(q[o1] > 0 && q[o1] < MESH_BLOCK && q[o2] > 0 && q[o2] < MESH_BLOCK);
    for (int d2 = 0; d2 < 2 && on_face; d2++)
        for (int d1 = 0; d1 < 2; d1++) {
            int cell[3] = { q[0], q[1], q[2] };
            cell[o1] -= d1;
            cell[o2] -= d2;
            int off[3];
            for (int k = 0; k < 3; k++)
                off[k] = cell[k] < 0 ? -1 : (cell[k] >= MESH_BLOCK ? 1 : 0);
            if (off[0] || off[1] || off[2])
                B->need |= 1u << ((off[0] + 1) + 3 * (off[1] + 1) + 9 * (off[2] + 1));
        }
}

/* A crossing on a box cap (one end is padding): it sits on the real (inside) corner,
 * its normal points out of the box. */
static void cap_crossing(block_ctx *c, int id, int ci, int a, const double p0[3],
                         const double p1[3])
{
    mwork *W = c->W;
    c->B->virtual_crossings++;
    int in0 = W->cin[ci];
    W->px[id] = in0 ? p0[0] : p1[0];
    W->py[id] = in0 ? p0[1] : p1[1];
    W->pz[id] = in0 ? p0[2] : p1[2];
    W->nx[id] = W->ny[id] = W->nz[id] = 0;
    double sg = in0 ? 1.0 : -1.0;
    if (a == 0) W->nx[id] = sg;
    else if (a == 1) W->ny[id] = sg;
    else W->nz[id] = sg;
}

/* A crossing between two real corners: its bracket [0, 1] along the edge p0 -> p1
 * for the root finder. */
static void root_crossing(block_ctx *c, int id, int ci, int cj, const double p0[3],
                          const double p1[3])
{
    mwork *W = c->W;
    c->B->real_crossings++;
    int r = c->nroot++;
    W->rid[r] = id;
    W->ax[r] = p0[0]; W->ay[r] = p0[1]; W->az[r] = p0[2];
    W->dx[r] = p1[0] - p0[0]; W->dy[r] = p1[1] - p0[1]; W->dz[r] = p1[2] - p0[2];
    W->t0[r] = 0; W->g0[r] = W->cf[ci] - c->iso;
    W->t1[r] = 1; W->g1[r] = W->cf[cj] - c->iso;
    W->side[r] = 0;
}

/* The crossing edge from corner q along axis a: number it, mark the neighbours it
 * needs, and set up its root finding or its cap. */
static void add_crossing(block_ctx *c, const int q[3], int a)
{
    int ci = corner_index(q[0], q[1], q[2]);
    int id = c->ncross++;
    c->W->eidx[3 * ci + a] = id;
    int q2[3] = { q[0], q[1], q[2] };
    q2[a]++;
    int real0 = c->creal[0][q[0]] && c->creal[1][q[1]] && c->creal[2][q[2]];
    int real1 = c->creal[0][q2[0]] && c->creal[1][q2[1]] && c->creal[2][q2[2]];
    double p0[3] = { c->cc[0][q[0]], c->cc[1][q[1]], c->cc[2][q[2]] };
    double p1[3] = { c->cc[0][q2[0]], c->cc[1][q2[1]], c->cc[2][q2[2]] };
    mark_needed(c->B, q, a);
    if (real0 && real1) root_crossing(c, id, ci, ci + cstride[a], p0, p1);
    else cap_crossing(c, id, ci, a, p0, p1);
}

/* 2. The sign-changing edges, found a row of edges along x at a time from bit rows of
 * the corners' sides (most rows have none). */
static void find_crossings(block_ctx *c)
{
    mwork *W = c->W;
    c->ncross = c->nroot = 0;
    memset(W->eidx, 0xFF, sizeof W->eidx);  /* -1: no crossing */
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++) {
            unsigned m = 0;
            for (int i = 0; i <= MESH_BLOCK; i++) m |= (unsigned)W->cin[corner_index(i, j, k)] << i;
            W->rows[k][j] = m;
        }
    for (int k = 0; k <= MESH_BLOCK; k++)
        for (int j = 0; j <= MESH_BLOCK; j++)
            for (int a = 0; a < 3; a++) {
                unsigned row = W->rows[k][j], cross;
                if (a == 0) cross = (row ^ (row >> 1)) & ((1u << MESH_BLOCK) - 1);
                else if (a == 1) cross = j < MESH_BLOCK ? row ^ W->rows[k][j + 1] : 0;
                else cross = k < MESH_BLOCK ? row ^ W->rows[k + 1][j] : 0;
                for (int i = 0; cross; i++, cross >>= 1) {
                    if (!(cross & 1)) continue;
                    const int q[3] = { i, j, k };
                    add_crossing(c, q, a);
                }
            }
}

/* The crossings whose bracket is still too wide get their next guess into the batch
 * (qx, qy, qz; act); the others are marked converged.  Returns the batch size. */
static int root_batch(mwork *W, int nroot)
{
    int na = 0;
    for (int r = 0; r < nroot; r++) {
        if (W->side[r] >= 2) continue;
        double t = root_guess(W, r);
        if (W->t1[r] - W->t0[r] <= MESH_ROOT_TOL || W->g0[r] == 0 || W->g1[r] == 0) {
            W->side[r] = 2; /* converged: the final guess lands here */
            continue;
        }
        W->tt[r] = t;
        W->act[na] = r;
        W->qx[na] = W->ax[r] + t * W->dx[r];
        W->qy[na] = W->ay[r] + t * W->dy[r];
        W->qz[na] = W->az[r] + t * W->dz[r];
        na++;
    }
    return na;
}

/* Shrink the brackets by the batch's values (Illinois: halve the far end's value when
 * the same end moved twice, so that it does not stick). */
static void root_update(mwork *W, int na, double iso)
{
    for (int q = 0; q < na; q++) {
        int r = W->act[q];
        double gv = W->qf[q] - iso;
        int in_t = W->qf[q] >= iso, in_0 = W->g0[r] >= 0;
        if (in_t == in_0) {
            W->t0[r] = W->tt[r];
            W->g0[r] = gv;
            if (W->side[r] == -1) W->g1[r] *= 0.5;
            W->side[r] = -1;
        } else {
            W->t1[r] = W->tt[r];
            W->g1[r] = gv;
            if (W->side[r] == 1) W->g0[r] *= 0.5;
            W->side[r] = 1;
        }
        /* close: by the secant slope over the new bracket, the root is within
         * MESH_ROOT_FTOL of the edge */
        if (fabs(gv) * (W->t1[r] - W->t0[r]) <= MESH_ROOT_FTOL * fabs(W->g1[r] - W->g0[r]))
            W->side[r] = 3;
    }
}

/* Crossing r at parameter t of its edge: its place, and entry q of the batch. */
static void crossing_place(mwork *W, int r, int q, double t)
{
    int id = W->rid[r];
    W->tt[r] = t;
    W->px[id] = W->qx[q] = W->ax[r] + t * W->dx[r];
    W->py[id] = W->qy[q] = W->ay[r] + t * W->dy[r];
    W->pz[id] = W->qz[q] = W->az[r] + t * W->dz[r];
}

/* 3. Root finding on the real crossings (Illinois regula falsi, batched: each step
 * evaluates only the crossings whose bracket is still too wide); each crossing goes
 * to its final guess, also put in the batch for the gradient. */
static int find_roots(block_ctx *c)
{
    mwork *W = c->W;
    for (int r = 0; r < c->nroot; r++) W->tt[r] = NAN;
    for (int step = 0; step < MESH_ROOT_STEPS && c->nroot > 0; step++) {
        int na = root_batch(W, c->nroot);
        if (na == 0) break;
        if (c->f->eval(c->f->ctx, c->ts, (size_t)na, W->qx, W->qy, W->qz, W->qf) != 0)
            return FREP_EINPUT;
        W->eval_points += (size_t)na;
        root_update(W, na, c->iso);
    }
    for (int r = 0; r < c->nroot; r++) crossing_place(W, r, r, root_guess(W, r));
    return 0;
}

/* Crossing r from its value and gradient at entry q of the batch (qf, gx, gy, gz): one
 * Newton step along the edge, kept only inside the bracket (a kink of a CSG field may
 * send it anywhere), and the normal.  Returns whether the step was kept. */
static int crossing_refine(mwork *W, int r, int q, double iso)
{
    int id = W->rid[r];
    double fd = W->gx[q] * W->dx[r] + W->gy[q] * W->dy[r] + W->gz[q] * W->dz[r];
    double tn = fd != 0 ? W->tt[r] - (W->qf[q] - iso) / fd : NAN;
    int kept = tn >= W->t0[r] && tn <= W->t1[r];
    if (kept) {
        W->px[id] = W->ax[r] + tn * W->dx[r];
        W->py[id] = W->ay[r] + tn * W->dy[r];
        W->pz[id] = W->az[r] + tn * W->dz[r];
    }
    /* inside is f >= iso, so the gradient points inward */
    double n[3] = { -W->gx[q], -W->gy[q], -W->gz[q] };
    if (vec3_normalize(n)) {
        /* no usable gradient: the edge direction, from inside to outside */
        double s = W->g0[r] >= 0 ? 1.0 : -1.0;
        n[0] = s * W->dx[r];
        n[1] = s * W->dy[r];
        n[2] = s * W->dz[r];
        if (vec3_normalize(n)) n[0] = n[1] = n[2] = 0;
    }
    W->nx[id] = n[0];
    W->ny[id] = n[1];
    W->nz[id] = n[2];
    return kept;
}

/* The crossings act[0..n) (stopped by MESH_ROOT_FTOL, their Newton step out of the
 * bracket): MESH_ROOT_BISECT bisections in batches, the secant guess of the final
 * bracket, and its gradient for the Newton step and the normal. */
static int bisect_roots(block_ctx *c, int n)
{
    mwork *W = c->W;
    for (int step = 0; step < MESH_ROOT_BISECT; step++) {
        for (int q = 0; q < n; q++) {
            int r = W->act[q];
            crossing_place(W, r, q, 0.5 * (W->t0[r] + W->t1[r]));
        }
        if (c->f->eval(c->f->ctx, c->ts, (size_t)n, W->qx, W->qy, W->qz, W->qf) != 0)
            return FREP_EINPUT;
        W->eval_points += (size_t)n;
        for (int q = 0; q < n; q++) {
            int r = W->act[q];
            double gv = W->qf[q] - c->iso;
            if ((W->qf[q] >= c->iso) == (W->g0[r] >= 0)) { W->t0[r] = W->tt[r]; W->g0[r] = gv; }
            else { W->t1[r] = W->tt[r]; W->g1[r] = gv; }
        }
    }
    for (int q = 0; q < n; q++) crossing_place(W, W->act[q], q, root_guess(W, W->act[q]));
    if (c->f->grad(c->f->ctx, c->ts, (size_t)n, W->qx, W->qy, W->qz, W->qf, W->gx, W->gy,
                   W->gz) != 0)
        return FREP_EINPUT;
    W->grad_points += (size_t)n;
    for (int q = 0; q < n; q++) crossing_refine(W, W->act[q], q, c->iso);
    return 0;
}

/* Whether crossing r, stopped by MESH_ROOT_FTOL, lies where the field is flatter than
 * over its bracket: the slope along the edge at the final point has the secant's sign
 * and puts the root more than MESH_ROOT_FTOL of the edge away, and the point is more
 * than MESH_ROOT_NEAR from the surface.  (A slope of the other
 * sign is a ridge between two sheets, as where a sphere cuts the gyroid: the root is
 * past it either way, and bisected there the gyroid's crossings folded its quads,
 * bench/bench_gyroid.hf at -g 24 and 53 in tests/mesh.sh's shifted boxes.) */
static int root_flat(const mesher *M, const mwork *W, int r, double iso)
{
    double fd = W->gx[r] * W->dx[r] + W->gy[r] * W->dy[r] + W->gz[r] * W->dz[r];
    return fd * (W->g1[r] - W->g0[r]) > 0 && fabs(W->qf[r] - iso) > MESH_ROOT_FTOL * fabs(fd) &&
           mesh_cell_distance(M, W->qf[r] - iso, W->gx[r], W->gy[r], W->gz[r]) > MESH_ROOT_NEAR;
}

/* The gradient at every real crossing, in one batch, refines it and gives its normal;
 * the crossings the slope stopped whose Newton step failed are bisected further. */
static int crossing_normals(block_ctx *c)
{
    mwork *W = c->W;
    if (c->nroot > 0 && c->f->grad(c->f->ctx, c->ts, (size_t)c->nroot, W->qx, W->qy, W->qz,
                                   W->qf, W->gx, W->gy, W->gz) != 0)
        return FREP_EINPUT;
    W->grad_points += (size_t)c->nroot;
    int n = 0;
    for (int r = 0; r < c->nroot; r++)
        if (!crossing_refine(W, r, r, c->iso) && W->side[r] == 3 && root_flat(c->M, W, r, c->iso))
            W->act[n++] = r;
    return n > 0 ? bisect_roots(c, n) : 0;
}

/* Bit i: the face across axis a from corner (i, j, k) of the block is ambiguous, its
 * inside corners on a diagonal (faces beyond the block's corners excluded). */
static unsigned ambiguous_row(const mwork *W, int a, int j, int k)
{
    const uint32_t(*rows)[MESH_BLOCK + 1] = W->rows;
    uint32_t r00 = rows[k][j], r10, r01, r11;
    unsigned mask = (1u << MESH_BLOCK) - 1;
    if (a == 0) {
        if (j == MESH_BLOCK || k == MESH_BLOCK) return 0;
        r10 = rows[k][j + 1];
        r01 = rows[k + 1][j];
        r11 = rows[k + 1][j + 1];
        mask = (1u << (MESH_BLOCK + 1)) - 1;
    } else {
        /* x and the face's other axis (y for a == 2, z for a == 1) */
        if (a == 2 ? j == MESH_BLOCK : k == MESH_BLOCK) return 0;
        r10 = r00 >> 1;
        r01 = a == 2 ? rows[k][j + 1] : rows[k + 1][j];
        r11 = r01 >> 1;
    }
    /* corner 00 differs from both neighbours on the face and equals its diagonal */
    return (r00 ^ r10) & (r00 ^ r01) & ~(r00 ^ r11) & mask;
}

/* The ambiguous faces' topology, decided by the field at the face's centre: inside
 * (f >= iso) joins the inside corners across the face, else they are separated.  The
 * decision depends on the face alone (its centre's coordinates come from the global
 * grid, values near the level from the whole program), so both cells sharing a face
 * agree.  A fixed rule (always separating the inside corners) split the surface of a
 * convex solid wherever its sharp rim crossed a face diagonally: a cell of
 * tests/models/segment_cone.hf at -b 1.2 -g 256 holding two flat sheets, its cap and
 * its side, got two components each mixing both sheets' crossings, whose vertices
 * landed a cell off the surface and folded over the neighbours' (106 self-
 * intersecting pairs).  The four corners of an ambiguous face are real grid points
 * (its inside corners are, and they span both of its axes).  Fills W->fjoin. */
static int face_decisions(block_ctx *c)
{
    mwork *W = c->W;
    size_t n = 0;
    c->joined = 0;
    for (int a = 0; a < 3; a++) {
        int o1, o2;
        mesh_edge_other_axes(a, &o1, &o2);
        for (int k = 0; k <= MESH_BLOCK; k++)
            for (int j = 0; j <= MESH_BLOCK; j++)
                for (unsigned amb = ambiguous_row(W, a, j, k), i = 0; amb; i++, amb >>= 1) {
                    if (!(amb & 1)) continue;
                    const int q[3] = { (int)i, j, k };
                    double p[3];
                    p[a] = c->cc[a][q[a]];
                    p[o1] = 0.5 * (c->cc[o1][q[o1]] + c->cc[o1][q[o1] + 1]);
                    p[o2] = 0.5 * (c->cc[o2][q[o2]] + c->cc[o2][q[o2] + 1]);
                    W->act[n] = 3 * corner_index(q[0], q[1], q[2]) + a;
                    W->qx[n] = p[0];
                    W->qy[n] = p[1];
                    W->qz[n] = p[2];
                    n++;
                }
    }
    if (n == 0) return 0;
    if (c->f->eval(c->f->ctx, c->ts, n, W->qx, W->qy, W->qz, W->qf) != 0) return FREP_EINPUT;
    W->eval_points += n;
    if (c->focused && c->sign_tol > 0) {
        int rc = recheck_near_level(c, n, W->qx, W->qy, W->qz, W->qf);
        if (rc) return rc;
    }
    memset(W->fjoin, 0, sizeof W->fjoin);
    for (size_t q = 0; q < n; q++)
        if (W->qf[q] >= c->iso) {
            W->fjoin[W->act[q] / 3] |= (uint8_t)(1u << (W->act[q] % 3));
            c->joined = 1;
        }
    return 0;
}

/* A face that one surface component of a cell crosses twice (two segments, each
 * cutting off one corner: an inside one, or an outside one where the face joins its
 * inside corners) would join that component's vertex to the vertex of
 * the cell across the face twice, once per segment: if the component across the face
 * also crosses it twice, four quads share that mesh edge and the mesh is not
 * 2-manifold there (a tunnel thinner than a cell).  Such a face gets one vertex per
 * segment, between its two crossings, which the quads of the segment's crossing edges
 * take as an extra corner: the two mesh edges become four distinct ones.  Here the
 * candidates: the low faces (s = 0) of cell (i, j, k) that its own component crosses
 * twice; mesh_resolve_faces() keeps those whose other side does so too.  Segment 0 is
 * the one cutting off the corner with the lower coordinate along the face's first
 * axis.  Returns the new number of candidates. */
static size_t face_candidates(mwork *W, int cf, int dup, int i, int j, int k, size_t nf)
{
    int cell = mesh_cell_index(i, j, k);
    for (int a = 0; a < 3; a++) {
        if (!(dup & (1 << (2 * a)))) continue;
        int ax[2];
        mesh_edge_other_axes(a, &ax[0], &ax[1]);
        W->fkey[nf] = (uint16_t)(3 * cell + a);
        int cut = !mesh_face_joined(cf, a, 0);  /* the side of the corners cut off */
        for (int c = 0; c < 8; c++) {
            if (((c >> a) & 1) || ((cf >> c) & 1) != cut) continue;
            size_t q = 2 * nf + (size_t)((c >> ax[0]) & 1);
            double p[3] = { 0, 0, 0 }, n[3] = { 0, 0, 0 };
            int np = 0;
            for (int t = 0; t < 2; t++) {
                int b = ax[t], lo = c & ~(1 << b);
                int ci = corner_index(i + (lo & 1), j + ((lo >> 1) & 1), k + ((lo >> 2) & 1));
                int id = W->eidx[3 * ci + b];
                if (id < 0) continue;
                p[0] += W->px[id];
                p[1] += W->py[id];
                p[2] += W->pz[id];
                n[0] += W->nx[id];
                n[1] += W->ny[id];
                n[2] += W->nz[id];
                np++;
            }
            if (np == 0) np = 1;
            W->sx[q] = p[0] / np;
            W->sy[q] = p[1] / np;
            W->sz[q] = p[2] / np;
            vec3_normalize(n);  /* unit or zero normals: a zero sum stays zero */
            W->snx[q] = n[0];
            W->sny[q] = n[1];
            W->snz[q] = n[2];
        }
        nf++;
    }
    return nf;
}

/* Whether a corner of cell L is exactly on the level. */
static int cell_on_level(const block_ctx *c, const int L[3])
{
    for (int k = 0; k < 8; k++)
        if (c->W->cf[corner_index(L[0] + (k & 1), L[1] + ((k >> 1) & 1), L[2] + (k >> 2))] == c->iso)
            return 1;
    return 0;
}

/* Whether all np crossings lie on one face of the cell [lo, hi] (within MESH_CLAMP of
 * a cell): the surface in the cell is that face (see MESH_QEF_FIT). */
static int crossings_on_face(int np, const double (*p)[3], const double lo[3], const double hi[3])
{
    for (int c = 0; c < 3; c++) {
        double tol = MESH_CLAMP * (hi[c] - lo[c]);
        int nlo = 0, nhi = 0;
        for (int i = 0; i < np; i++) {
            nlo += p[i][c] <= lo[c] + tol;
            nhi += p[i][c] >= hi[c] - tol;
        }
        if (nlo == np || nhi == np) return 1;
    }
    return 0;
}

/* The vertex of component cyc of cell L (configuration cf, box [lo, hi]): the QEF
 * minimizer of the component's crossings (the cell's centre when it has none), with
 * the mean of their normals. */
static void component_vertex(block_ctx *c, int cf, int cyc, const int L[3],
                             const double lo[3], const double hi[3])
{
    mwork *W = c->W;
    double pts[12][3], nrm[12][3], sn[3] = { 0, 0, 0 };
    int np = 0;
    for (int e = 0; e < 12; e++) {
        if (c->M->table.cycle[cf][e] != cyc) continue;
        int s0 = edge_start(e);
        int ci = corner_index(L[0] + (s0 & 1), L[1] + ((s0 >> 1) & 1), L[2] + ((s0 >> 2) & 1));
        int id = W->eidx[3 * ci + e / 4];
        if (id < 0) continue;
        pts[np][0] = W->px[id];
        pts[np][1] = W->py[id];
        pts[np][2] = W->pz[id];
        nrm[np][0] = W->nx[id];
        nrm[np][1] = W->ny[id];
        nrm[np][2] = W->nz[id];
        for (int k = 0; k < 3; k++) sn[k] += nrm[np][k];
        np++;
    }
    double x[3], alt[3] = { 0, 0, 0 };
    int rank = 0, alt_rank = 0;
    if (np == 0) {
        for (int k = 0; k < 3; k++) x[k] = 0.5 * (lo[k] + hi[k]);
    } else {
        double reach = c->M->o->no_projection || !cell_on_level(c, L) ? 0 : MESH_QEF_REACH;
        /* the sampler's mesh keeps its feature solutions MESH_CLAMP inside the cell */
        int clamp_fit = !c->M->o->no_projection &&
                        !crossings_on_face(np, (const double(*)[3])pts, lo, hi);
        rank = qef_solve(np, (const double(*)[3])pts, (const double(*)[3])nrm, lo, hi, reach,
                         clamp_fit, x, alt, &alt_rank);
    }
    size_t nv = c->nv++;
    W->vrank[nv] = (uint8_t)rank;
    W->altrank[nv] = (uint8_t)(rank == 0 ? alt_rank : 0);
    if (W->altrank[nv]) {
        W->altx[nv] = alt[0];
        W->alty[nv] = alt[1];
        W->altz[nv] = alt[2];
    }
    W->vcell[nv] = (uint16_t)mesh_cell_index(L[0], L[1], L[2]);
    W->vx[nv] = x[0];
    W->vy[nv] = x[1];
    W->vz[nv] = x[2];
    W->vone[nv] = np > 0 && vec3_len(sn) >= MESH_PROJECT_ONE_WAY * np;
    vec3_normalize(sn);  /* unit or zero normals: a zero sum stays zero */
    W->fnx[nv] = sn[0];
    W->fny[nv] = sn[1];
    W->fnz[nv] = sn[2];
}

/* Cell L's configuration (the case, corner c = x + 2y + 4z: two bits from each of
 * four rows, and its joined faces), its first vertex and one vertex per component;
 * its face candidates. */
static void cell_components(block_ctx *c, const int L[3])
{
    const mesher *M = c->M;
    mwork *W = c->W;
    int i = L[0], j = L[1], k = L[2];
    int cell = mesh_cell_index(i, j, k);
    W->vbase[cell] = MESH_NO_VERTEX;
    if (c->base[0] + i >= M->G[0] || c->base[1] + j >= M->G[1] || c->base[2] + k >= M->G[2]) {
        W->cs[cell] = 0;
        return;
    }
    uint32_t(*rows)[MESH_BLOCK + 1] = c->W->rows;
    int cf = (int)(((rows[k][j] >> i) & 3u) | (((rows[k][j + 1] >> i) & 3u) << 2) |
                   (((rows[k + 1][j] >> i) & 3u) << 4) | (((rows[k + 1][j + 1] >> i) & 3u) << 6));
    const uint8_t *fj = c->W->fjoin;
    for (int a = 0; a < 3 && c->joined; a++) {
        int c0 = corner_index(i, j, k), c1 = c0 + cstride[a];
        cf |= ((fj[c0] >> a) & 1) << (MESH_FACE_SHIFT + 2 * a);
        cf |= ((fj[c1] >> a) & 1) << (MESH_FACE_SHIFT + 2 * a + 1);
    }
    W->cs[cell] = (uint16_t)cf;
    int ncyc = M->table.ncycles[cf];
    if (ncyc == 0) return;
    if (ncyc > 1) c->B->split_cells++;
    W->vbase[cell] = (uint16_t)c->nv;
    double lo[3], hi[3];
    for (int q = 0; q < 3; q++) {
        lo[q] = corner_coord(M, q, c->base[q] + L[q]);
        hi[q] = corner_coord(M, q, c->base[q] + L[q] + 1);
    }
    for (int cyc = 0; cyc < ncyc; cyc++) component_vertex(c, cf, cyc, L, lo, hi);
    if (M->table.dupface[cf] & 0x15)
        c->nf = face_candidates(c->W, cf, M->table.dupface[cf], i, j, k, c->nf);
}

/* 4. One vertex per surface component of each cell, and the face candidates. */
static int cell_vertices(block_ctx *c)
{
    mblock *B = c->B;
    c->nv = c->nf = 0;
    for (int k = 0; k < MESH_BLOCK; k++)
        for (int j = 0; j < MESH_BLOCK; j++)
            for (int i = 0; i < MESH_BLOCK; i++) {
                const int L[3] = { i, j, k };
                cell_components(c, L);
            }
    B->nverts = (uint32_t)c->nv;
    B->nfaces = (uint32_t)c->nf;
    if (c->nv == 0) return 0;
    mpool *cells = &c->mem->pool[MESH_POOL_CELLS];
    B->cs = mesh_pool_alloc(cells, MESH_BLOCK_CELLS * sizeof *B->cs);
    B->vbase = mesh_pool_alloc(cells, MESH_BLOCK_CELLS * sizeof *B->vbase);
    if (!B->cs || !B->vbase) return FREP_ENOMEM;
    memcpy(B->cs, c->W->cs, MESH_BLOCK_CELLS * sizeof *B->cs);
    memcpy(B->vbase, c->W->vbase, MESH_BLOCK_CELLS * sizeof *B->vbase);
    return 0;
}

/* The face candidates' keys into the block and their vertices after the cell
 * vertices (rank 0: they are not QEF solutions). */
static int append_face_vertices(block_ctx *c)
{
    mwork *W = c->W;
    size_t nv = c->nv, nf = c->nf;
    if (nf == 0) return 0;
    c->B->fkey = mesh_pool_alloc(&c->mem->pool[MESH_POOL_CELLS], nf * sizeof *c->B->fkey);
    if (!c->B->fkey) return FREP_ENOMEM;
    memcpy(c->B->fkey, W->fkey, nf * sizeof *c->B->fkey);
    for (size_t q = 0; q < 2 * nf; q++) {
        W->vx[nv + q] = W->sx[q];
        W->vy[nv + q] = W->sy[q];
        W->vz[nv + q] = W->sz[q];
        W->fnx[nv + q] = W->snx[q];
        W->fny[nv + q] = W->sny[q];
        W->fnz[nv + q] = W->snz[q];
        W->vrank[nv + q] = 0;
    }
    return 0;
}

/* Vertex v into the block: position, f - iso and gradient, and the normal -grad f
 * (the crossings' normals on a box cap, or where the gradient says nothing or
 * disagrees). */
static void store_vertex(block_ctx *c, size_t v)
{
    const mwork *W = c->W;
    mblock *B = c->B;
    B->vpos[3 * v] = W->vx[v];
    B->vpos[3 * v + 1] = W->vy[v];
    B->vpos[3 * v + 2] = W->vz[v];
    B->vfg[4 * v] = W->vf[v] - c->iso;
    B->vfg[4 * v + 1] = W->vgx[v];
    B->vfg[4 * v + 2] = W->vgy[v];
    B->vfg[4 * v + 3] = W->vgz[v];
    double n[3] = { -W->vgx[v], -W->vgy[v], -W->vgz[v] };
    const double fn[3] = { W->fnx[v], W->fny[v], W->fnz[v] };
    if (vec3_normalize(n) || vec3_dot(n, fn) < 0) memcpy(n, fn, sizeof n);
    memcpy(&B->vnrm[3 * v], n, sizeof n);
}

/* The box of cell vertex v's cell, shrunk by margin (a fraction of the cell); 0 when
 * the vertex is not to be projected: its cell is in the padding layer (its vertices
 * may lie on a box cap, off the surface), has several components, or has a corner
 * exactly on the level. */
static int vertex_cell_box(const block_ctx *c, size_t v, double margin, double lo[3],
                           double hi[3])
{
    int cell = c->W->vcell[v];
    if (c->M->table.ncycles[c->W->cs[cell]] > 1) return 0;
    const int L[3] = { cell % MESH_BLOCK, (cell / MESH_BLOCK) % MESH_BLOCK,
                       cell / (MESH_BLOCK * MESH_BLOCK) };
    /* a corner exactly on the level: a sheet along the cell's faces, shared with the
     * neighbours, which projection would fold over them */
    if (cell_on_level(c, L)) return 0;
    for (int q = 0; q < 3; q++) {
        long C = c->base[q] + L[q];
        if (C == 0 || C + 1 >= c->M->G[q]) return 0;
        double a = corner_coord(c->M, q, C), b = corner_coord(c->M, q, C + 1);
        double s = margin * (b - a);
        lo[q] = a + s;
        hi[q] = b - s;
    }
    return 1;
}

/* How near the surface vertex v is projected (cells): MESH_PROJECT_TOL, or
 * MESH_PROJECT_TOL_MASS for a mass point. */
static double project_tol(const mwork *W, size_t v)
{
    return W->vrank[v] == 0 ? MESH_PROJECT_TOL_MASS : MESH_PROJECT_TOL;
}

/* Vertex v moves to sample q of the batch (jx.. jgz): its position, value and
 * gradient. */
static void take_sample(mwork *W, size_t v, int q)
{
    W->vx[v] = W->jx[q];
    W->vy[v] = W->jy[q];
    W->vz[v] = W->jz[q];
    W->vf[v] = W->jf[q];
    W->vgx[v] = W->jgx[q];
    W->vgy[v] = W->jgy[q];
    W->vgz[v] = W->jgz[q];
}

/* The cell vertices farther than project_tol cells from the surface (the QEF's
 * solution off a curved sheet, or the mass point where the solution left the cell)
 * go to the surface by Newton steps x - (f - iso) grad f / |grad f|^2, clamped to
 * their cell less MESH_PROJECT_MARGIN, each kept only when it brings the vertex
 * closer and reaches a sheet facing about the way of the component's crossings.  Sharp
 * features stay: a corner or edge solution of the QEF is on the surface already. */
static int project_vertices(block_ctx *c)
{
    mwork *W = c->W;
    const mesher *M = c->M;
    int n = 0;
    if (M->o->no_projection) return 0;
    for (size_t v = 0; v < c->nv; v++) {
        double d = mesh_cell_distance(M, W->vf[v] - c->iso, W->vgx[v], W->vgy[v], W->vgz[v]);
        if (d > project_tol(W, v)) W->jid[n++] = (int32_t)v;
    }
    for (int step = 0; step < MESH_PROJECT_STEPS && n > 0; step++) {
        int m = 0;
        for (int q = 0; q < n; q++) {
            size_t v = (size_t)W->jid[q];
            double lo[3], hi[3];
            if (!vertex_cell_box(c, v, MESH_PROJECT_MARGIN, lo, hi)) continue;
            double g[3] = { W->vgx[v], W->vgy[v], W->vgz[v] };
            double t = (W->vf[v] - c->iso) / vec3_dot(g, g);
            double x[3] = { W->vx[v] - t * g[0], W->vy[v] - t * g[1], W->vz[v] - t * g[2] };
            for (int k = 0; k < 3; k++) x[k] = fmin(fmax(x[k], lo[k]), hi[k]);
            W->jid[m] = (int32_t)v;
            W->jx[m] = x[0];
            W->jy[m] = x[1];
            W->jz[m] = x[2];
            m++;
        }
        if (m == 0) break;
        if (c->f->grad(c->f->ctx, c->ts, (size_t)m, W->jx, W->jy, W->jz, W->jf, W->jgx, W->jgy,
                       W->jgz) != 0)
            return FREP_EINPUT;
        W->grad_points += (size_t)m;
        n = 0;
        for (int q = 0; q < m; q++) {
            size_t v = (size_t)W->jid[q];
            double d0 = mesh_cell_distance(M, W->vf[v] - c->iso, W->vgx[v], W->vgy[v], W->vgz[v]);
            double d1 = mesh_cell_distance(M, W->jf[q] - c->iso, W->jgx[q], W->jgy[q], W->jgz[q]);
            /* the surface reached must face the way of the component's crossings (not
             * another sheet in the cell, as of a part a hair's breadth away), or across
             * a crease (see MESH_PROJECT_FACING) */
            double fd = -(W->jgx[q] * W->fnx[v] + W->jgy[q] * W->fny[v] + W->jgz[q] * W->fnz[v]);
            double gl = sqrt(W->jgx[q] * W->jgx[q] + W->jgy[q] * W->jgy[q] + W->jgz[q] * W->jgz[q]);
            int facing = fd > (W->vone[v] ? MESH_PROJECT_FACING : 0) * gl &&
                         (W->fnx[v] != 0 || W->fny[v] != 0 || W->fnz[v] != 0);
            if (!(d1 < d0) || !facing) continue;
            take_sample(W, v, q);
            if (d1 > project_tol(W, v)) W->jid[n++] = (int32_t)v;
        }
    }
    return 0;
}

/* The mass points (rank 0) off the surface, in cells where project_vertices does not
 * move them (a corner on the level, several components), whose edge or corner
 * solution, clamped into the cell, missed a crossing's tangent plane: the clamped
 * point replaces the mass point when the field puts it within MESH_QEF_FIT of a cell
 * of the surface.
 * The tangent planes stand in for the surface near the crossings; a clamped point
 * where only some of the cell's sheets are (a block's face on a grid plane beside a
 * gap the others end at) misses the planes of the others, yet lies on the surface. */
static int clamped_on_surface(block_ctx *c)
{
    mwork *W = c->W;
    const mesher *M = c->M;
    int m = 0;
    for (size_t v = 0; v < c->nv; v++) {
        double lo[3], hi[3];
        if (!W->altrank[v] ||
            mesh_cell_distance(M, W->vf[v] - c->iso, W->vgx[v], W->vgy[v], W->vgz[v]) <=
                project_tol(W, v) ||
            vertex_cell_box(c, v, MESH_PROJECT_MARGIN, lo, hi))
            continue;
        W->jid[m] = (int32_t)v;
        W->jx[m] = W->altx[v];
        W->jy[m] = W->alty[v];
        W->jz[m] = W->altz[v];
        m++;
    }
    if (m == 0) return 0;
    if (c->f->grad(c->f->ctx, c->ts, (size_t)m, W->jx, W->jy, W->jz, W->jf, W->jgx, W->jgy,
                   W->jgz) != 0)
        return FREP_EINPUT;
    W->grad_points += (size_t)m;
    for (int q = 0; q < m; q++) {
        size_t v = (size_t)W->jid[q];
        double d = mesh_cell_distance(M, W->jf[q] - c->iso, W->jgx[q], W->jgy[q], W->jgz[q]);
        if (!(d <= MESH_QEF_FIT)) continue;
        take_sample(W, v, q);
        W->vrank[v] = W->altrank[v];
    }
    return 0;
}

/* 5. Every vertex's value and gradient, in one batch, and the block's vertex arrays. */
static int block_vertices(block_ctx *c)
{
    mwork *W = c->W;
    mblock *B = c->B;
    int rc = append_face_vertices(c);
    if (rc) return rc;
    size_t nall = c->nv + 2 * c->nf;
    mpool *pool = c->mem->pool;
    B->vpos = mesh_pool_alloc(&pool[MESH_POOL_POS], 3 * nall * sizeof *B->vpos);
    B->vnrm = mesh_pool_alloc(&pool[MESH_POOL_NRM], 3 * nall * sizeof *B->vnrm);
    B->vfg = mesh_pool_alloc(&pool[MESH_POOL_FG], 4 * nall * sizeof *B->vfg);
    B->vrank = mesh_pool_alloc(&pool[MESH_POOL_FG], nall);
    if (!B->vpos || !B->vnrm || !B->vfg || !B->vrank) return FREP_ENOMEM;
    if (c->f->grad(c->f->ctx, c->ts, nall, W->vx, W->vy, W->vz, W->vf, W->vgx, W->vgy, W->vgz) != 0)
        return FREP_EINPUT;
    W->grad_points += nall;
    if ((rc = clamped_on_surface(c)) != 0 || (rc = project_vertices(c)) != 0) return rc;
    memcpy(B->vrank, W->vrank, nall);
    for (size_t v = 0; v < nall; v++) store_vertex(c, v);
    return 0;
}

int mesh_block_contour(const mesher *M, mwork *W, mmem *mem, void *ts, mblock *B)
{
    block_ctx c = { .M = M, .W = W, .mem = mem, .ts = ts, .B = B, .f = M->f, .iso = M->o->iso };
    for (int k = 0; k < 3; k++) c.base[k] = (long)B->b[k] * MESH_BLOCK;
    int rc = block_focus(&c);
    if (rc) return rc;
    corner_grid(&c);
    if ((rc = corner_values(&c)) != 0) return rc;
    find_crossings(&c);
    if ((rc = find_roots(&c)) != 0 || (rc = crossing_normals(&c)) != 0) return rc;
    if ((rc = face_decisions(&c)) != 0) return rc;
    if ((rc = cell_vertices(&c)) != 0) return rc;
    if (c.nv > 0 && (rc = block_vertices(&c)) != 0) return rc;
    /* 6. the field back to the whole program */
    return c.focused ? field_status(c.f->focus(c.f->ctx, ts, NULL, NULL)) : 0;
}
