/* trimesh.h - the indexed triangle mesh of frep: what the polygonizer (mesh/mesh.c)
 * makes, the mesh files (geom/meshio.c) read and write, and sampling and rendering use.
 */
#ifndef FREP_TRIMESH_H
#define FREP_TRIMESH_H

#include <stddef.h>
#include <stdint.h>

/* A triangle mesh. v[3i..3i+2] is vertex i, n[3i..] its unit normal (zero when unknown),
 * tri[3t..3t+2] the vertices of triangle t, counter-clockwise seen from outside.
 * Free with mesh_free(). */
typedef struct frep_mesh {
    size_t nverts, ntris;
    double *v;
    double *n;        /* may be NULL (meshes read from files without normals) */
    uint32_t *tri;
} frep_mesh;

void mesh_free(frep_mesh *m);

/* A vertex colour from its position (what `frep mesh` asks of a colour source). */
typedef void (*mesh_color_fn)(void *user, const double p[3], uint8_t rgb[3]);
/* Every vertex's colour from fn: 3 bytes (red, green, blue) a vertex, in vertex order,
 * for meshio_write_colored().  Returns the array (free with frep_free) or NULL when
 * out of memory. */
uint8_t *mesh_colors(const frep_mesh *m, mesh_color_fn fn, void *user);

/* Checks used by the tests and `frep mesh --check`: counts of edges not shared by
 * exactly two triangles, of edges used twice in the same direction (orientation
 * flips), of triangles with (near) zero area and of non-finite coordinates, and of
 * non-manifold vertices: vertices whose triangles do not form one closed fan (two
 * cones touching at a point, or a fan left open).  Vertices no triangle uses are
 * counted apart (unused).  Self-intersections: pairs of triangles that share a point
 * other than their common vertices and edge (exact predicates, geom/tritri.c; pairs
 * sharing a vertex or an edge are tested too: a fold onto a neighbour counts). */
typedef struct mesh_check {
    size_t open_edges, nonmanifold_edges, flipped_edges, degenerate, nonfinite;
    double volume, area;     /* signed enclosed volume (positive when outward) */
    size_t nonmanifold_verts, unused_verts;
    size_t self_intersections;   /* intersecting triangle pairs: 0 from mesh_validate,
                                    counted by mesh_self_intersections (slower) */
} mesh_check;
/* Every count but the self-intersections. 0, or -1 when out of memory. */
int mesh_validate(const frep_mesh *m, mesh_check *c);

/* Do triangles s and t of m meet beyond their common vertices (found by index and put
 * first, in the same order)?  With x non-NULL, vertex v is taken at x instead (a move
 * being tried). */
int mesh_pair_meets(const frep_mesh *m, uint32_t s, uint32_t t, uint32_t v, const double *x);

/* The intersecting pairs of triangles of m (as in mesh_check) into *pairs; when
 * first is not NULL, the first such pair found (lower triangle first) into
 * first[0..1].  A uniform grid over the triangles' boxes keeps it near linear in the
 * number of triangles.  0, or -1 when out of memory. */
int mesh_self_intersections(const frep_mesh *m, size_t *pairs, uint32_t first[2]);

#endif
