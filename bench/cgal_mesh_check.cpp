// cgal_mesh_check.cpp - a second opinion on frep's meshes from CGAL (Debian libcgal-dev,
// header-only), for `make bench-cgal-mesh` only: never linked into frep.  Open3D's
// self-intersection test compares every pair of triangles, so it cannot check meshes of
// -g 128 and 256 (about 160,000 and 640,000 triangles) in reasonable time; CGAL's
// Polygon Mesh Processing tests pairs through an AABB tree with exact predicates (no
// tolerance: coplanar triangles that only meet a common line at different points are
// disjoint for it, as for frep's --check-intersections).
//
// usage: cgal_mesh_check MESH.off
// Prints one line:
//   triangles N closed 0|1 valid 0|1 self-intersecting-pairs K volume V
// valid: the polygon soup orients to a 2-manifold polygon mesh (CGAL's
// orient_polygon_soup found no non-manifold edge or vertex, and is_valid_polygon_mesh);
// volume: PMP::volume of the closed mesh, signed: positive when the triangles face
// outward (nan when open; orient_polygon_soup keeps a consistent soup's orientation).
// Exit 0 when the mesh is closed, valid, faces outward and has no self-intersecting
// pair; 1 otherwise; 2 when it cannot be read.
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Polygon_mesh_processing/measure.h>
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/self_intersections.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/IO/OFF.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <utility>
#include <vector>

typedef CGAL::Exact_predicates_inexact_constructions_kernel Kernel;
typedef Kernel::Point_3 Point;
typedef CGAL::Surface_mesh<Point> Mesh;
typedef boost::graph_traits<Mesh>::face_descriptor Face;
namespace PMP = CGAL::Polygon_mesh_processing;

int main(int argc, char **argv)
{
    if (argc != 2) {
        std::fprintf(stderr, "usage: cgal_mesh_check MESH.off\n");
        return 2;
    }
    std::vector<Point> points;
    std::vector<std::vector<std::size_t>> polygons;
    if (!CGAL::IO::read_OFF(argv[1], points, polygons) || polygons.empty()) {
        std::fprintf(stderr, "cgal_mesh_check: %s: cannot read it as OFF\n", argv[1]);
        return 2;
    }
    std::size_t ntri = polygons.size();
    // orient_polygon_soup returns false when it had to duplicate points to make the
    // soup manifold: the mesh as written is not a 2-manifold
    bool manifold = PMP::orient_polygon_soup(points, polygons);
    Mesh m;
    PMP::polygon_soup_to_polygon_mesh(points, polygons, m);
    bool valid = manifold && CGAL::is_valid_polygon_mesh(m);
    bool closed = CGAL::is_closed(m);
    std::vector<std::pair<Face, Face>> pairs;
    PMP::self_intersections(m, std::back_inserter(pairs));
    double volume = closed ? CGAL::to_double(PMP::volume(m)) : std::nan("");
    std::printf("triangles %zu closed %d valid %d self-intersecting-pairs %zu volume %.9g\n",
                ntri, closed ? 1 : 0, valid ? 1 : 0, pairs.size(), volume);
    return closed && valid && pairs.empty() && volume > 0 ? 0 : 1;
}
