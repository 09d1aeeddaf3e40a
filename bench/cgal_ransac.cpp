// cgal_ransac.cpp - CGAL's Efficient RANSAC (Schnabel et al. 2007, CGAL's
// Shape_detection package) on an oriented cloud, for `make bench-segment` only: the
// anchor frep's segmentation is compared with (bench/bench_segment_anchor.py). Never
// linked into frep; built by the bench target when libcgal-dev is installed.
//
// usage: cgal_ransac CLOUD.xyz SEED [epsilon cluster_epsilon min_points
//                                    normal_threshold probability]
// CLOUD.xyz: "x y z nx ny nz" a line (what `frep sample` writes). Without the five
// settings CGAL's defaults are used (epsilon and cluster_epsilon 1% of the bounding
// box diagonal, min_points 1% of the points, normal_threshold 0.9, probability 0.01).
// Writes the shapes found to stdout in frep's .fit format (geom/fitfile.c):
//   plane n d (n.x = d) / sphere c r / cylinder axis point r / cone axis apex angle /
//   torus axis center rminor rmajor
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Random.h>
#include <CGAL/Shape_detection/Efficient_RANSAC.h>
#include <CGAL/property_map.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

typedef CGAL::Exact_predicates_inexact_constructions_kernel Kernel;
typedef std::pair<Kernel::Point_3, Kernel::Vector_3> Pwn;
typedef std::vector<Pwn> Pwn_vector;
typedef CGAL::First_of_pair_property_map<Pwn> Point_map;
typedef CGAL::Second_of_pair_property_map<Pwn> Normal_map;
typedef CGAL::Shape_detection::Efficient_RANSAC_traits<Kernel, Pwn_vector, Point_map, Normal_map>
    Traits;
typedef CGAL::Shape_detection::Efficient_RANSAC<Traits> Ransac;
typedef CGAL::Shape_detection::Plane<Traits> Plane;
typedef CGAL::Shape_detection::Sphere<Traits> Sphere;
typedef CGAL::Shape_detection::Cylinder<Traits> Cylinder;
typedef CGAL::Shape_detection::Cone<Traits> Cone;
typedef CGAL::Shape_detection::Torus<Traits> Torus;

int main(int argc, char **argv)
{
    if (argc != 3 && argc != 8) {
        std::fprintf(stderr, "usage: %s CLOUD.xyz SEED [epsilon cluster_epsilon min_points "
                             "normal_threshold probability]\n", argv[0]);
        return 2;
    }
    std::ifstream in(argv[1]);
    if (!in) {
        std::fprintf(stderr, "%s: cannot open\n", argv[1]);
        return 1;
    }
    Pwn_vector pts;
    std::string line;
    while (std::getline(in, line)) {
        std::istringstream ls(line);
        double v[6];
        if (!(ls >> v[0] >> v[1] >> v[2] >> v[3] >> v[4] >> v[5])) continue;
        pts.push_back(Pwn(Kernel::Point_3(v[0], v[1], v[2]), Kernel::Vector_3(v[3], v[4], v[5])));
    }
    if (pts.empty()) {
        std::fprintf(stderr, "%s: no oriented points\n", argv[1]);
        return 1;
    }
    CGAL::get_default_random() = CGAL::Random((unsigned)std::strtoul(argv[2], 0, 10));
    Ransac ransac;
    ransac.set_input(pts);
    ransac.add_shape_factory<Plane>();
    ransac.add_shape_factory<Sphere>();
    ransac.add_shape_factory<Cylinder>();
    ransac.add_shape_factory<Cone>();
    ransac.add_shape_factory<Torus>();
    Ransac::Parameters par;
    if (argc == 8) {
        par.epsilon = std::atof(argv[3]);
        par.cluster_epsilon = std::atof(argv[4]);
        par.min_points = (std::size_t)std::atol(argv[5]);
        par.normal_threshold = std::atof(argv[6]);
        par.probability = std::atof(argv[7]);
    }
    if (argc == 8) ransac.detect(par);
    else ransac.detect();
    std::printf("# cgal_ransac: %zu shapes, %zu points unassigned\n",
                ransac.shapes().size(), ransac.number_of_unassigned_points());
    for (const auto &s : ransac.shapes()) {
        if (Plane *p = dynamic_cast<Plane *>(s.get())) {
            Kernel::Vector_3 n = p->plane_normal();
            std::printf("plane %.9g %.9g %.9g %.9g\n", n.x(), n.y(), n.z(), -p->d());
        } else if (Sphere *p = dynamic_cast<Sphere *>(s.get())) {
            Kernel::Point_3 c = p->center();
            std::printf("sphere %.9g %.9g %.9g %.9g\n", c.x(), c.y(), c.z(), p->radius());
        } else if (Cylinder *p = dynamic_cast<Cylinder *>(s.get())) {
            Kernel::Line_3 l = p->axis();
            Kernel::Vector_3 a = l.to_vector();
            a = a / std::sqrt(a.squared_length());
            Kernel::Point_3 q = l.point(0);
            std::printf("cylinder %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", a.x(), a.y(), a.z(),
                        q.x(), q.y(), q.z(), p->radius());
        } else if (Cone *p = dynamic_cast<Cone *>(s.get())) {
            Kernel::Vector_3 a = p->axis();
            Kernel::Point_3 q = p->apex();
            std::printf("cone %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", a.x(), a.y(), a.z(),
                        q.x(), q.y(), q.z(), p->angle());
        } else if (Torus *p = dynamic_cast<Torus *>(s.get())) {
            Kernel::Vector_3 a = p->axis();
            Kernel::Point_3 q = p->center();
            std::printf("torus %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", a.x(), a.y(), a.z(),
                        q.x(), q.y(), q.z(), p->minor_radius(), p->major_radius());
        }
    }
    return 0;
}
