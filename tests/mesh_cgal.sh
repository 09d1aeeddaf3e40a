#!/bin/sh
# mesh_cgal.sh - frep's meshes checked by CGAL (Debian libcgal-dev, header-only;
# bench/cgal_mesh_check.cpp, built here with the C++ compiler): closed, a valid
# 2-manifold polygon mesh, facing outward, no self-intersecting pair of triangles (an
# AABB tree and exact predicates), and the volume frep --check prints.  Open3D
# (tests/mesh_open3d.sh) compares every pair of triangles, so it stops at -g 64; CGAL
# checks -g 128 and 256 in seconds.  Each line also shows frep's own count of
# intersecting pairs and of vertices over 0.1 cell from the surface (tests/mesh.sh
# asserts those).  TAP output; skipped without CGAL or a C++ compiler.
#
# MESH_CGAL_GRIDS and MESH_CGAL_MODELS (paths relative to srcdir) widen it: `make
# bench-cgal-mesh` runs the whole suite of tests/mesh.sh at -g 32, 64, 128 and 256.
: "${FREP:=./frep}" "${srcdir:=.}"
T=${TMPDIR:-/tmp}/frep-mesh-cgal.$$
mkdir -p "$T" || exit 1
trap 'rm -rf "$T"' EXIT
CXX=${CXX_FOR_CGAL:-g++}
if ! command -v "$CXX" >/dev/null 2>&1 || [ ! -f /usr/include/CGAL/Surface_mesh.h ]; then
  echo "1..0 # SKIP CGAL or a C++ compiler is missing (apt-get install libcgal-dev g++)"
  exit 0
fi
if ! "$CXX" -O2 -DNDEBUG -std=c++17 "$srcdir/bench/cgal_mesh_check.cpp" -o "$T/check" \
     -lgmp -lmpfr 2>"$T/cxx.err"; then
  echo "1..0 # SKIP bench/cgal_mesh_check.cpp does not build with this CGAL: $(head -n 1 "$T/cxx.err")"
  exit 0
fi
GRIDS=${MESH_CGAL_GRIDS:-128}
# The default: models with sharp edges, holes meeting at angles and near-touching parts
# at a grid Open3D cannot check, and csg.hf at -g 256.
MODELS=${MESH_CGAL_MODELS:-"examples/csg.hf examples/bracket.hf examples/gear.hf \
  tests/models/sharp/holes.hf tests/models/sharp/near.hf tests/models/segment_cone.hf"}
echo "# $(nproc 2>/dev/null || echo '?') cores, load average: $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null)"
n=0
fails=0
run() { # run MODEL GRID
  hf=$srcdir/$1 g=$2
  case $1 in examples/*) b= ;; *) b="-b 1.2" ;; esac
  n=$((n + 1))
  # shellcheck disable=SC2086
  "$FREP" mesh "$hf" $b -g "$g" -o "$T/m.off" --check-intersections -q >"$T/out" 2>"$T/err"
  vol=$(sed -n 's/.*volume \([-0-9.e+]*\),.*/\1/p' "$T/out")
  own=$(sed -n 's/^check: \(self-intersecting triangle pairs [0-9]*\), vertices farther than 0.1 cell from the surface \([0-9]*\).*/\1, \2 far vertices/p' "$T/out")
  t0=$(date +%s.%N)
  r=$("$T/check" "$T/m.off" 2>&1)
  st=$?
  secs=$(awk -v a="$t0" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }')
  cv=$(echo "$r" | sed -n 's/.* volume \([-0-9.e+na]*\)$/\1/p')
  name="$(basename "$hf")${b:+ $b} -g $g"
  if [ -n "$vol" ] && [ $st = 0 ] &&
     awk -v a="$cv" -v b="$vol" 'BEGIN { d = a - b; if (d < 0) d = -d; exit !(d <= 1e-6 * (b < 0 ? -b : b)) }'; then
    echo "ok $n - $name in CGAL: $r (frep: volume $vol, $own; CGAL $secs s)"
  else
    echo "not ok $n - $name in CGAL: ${r:-no answer} (frep: volume ${vol:-failed}, $own)"
    sed 's/^/# /' "$T/err"
    fails=$((fails + 1))
  fi
}
for g in $GRIDS; do
  for m in $MODELS; do run "$m" "$g"; done
done
[ -n "$MESH_CGAL_MODELS$MESH_CGAL_GRIDS" ] || run examples/csg.hf 256
echo "1..$n"
test $fails -eq 0
