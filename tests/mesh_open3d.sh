#!/bin/sh
# mesh_open3d.sh - frep's meshes in another tool: Open3D (Debian python3-open3d, run by
# /usr/bin/python3) loads each mesh and finds it watertight, edge- and vertex-manifold,
# not self-intersecting, with the volume frep --check prints (TAP output).  Skipped when
# Open3D is not importable.  The gear is not in the list: Open3D (0.16) reports one pair
# of coplanar triangles on a flat tooth face at -g 32 that only share a line with each
# other's edge, which the exact test of --check finds disjoint.
: "${FREP:=./frep}" "${srcdir:=.}"
PY=/usr/bin/python3
T=${TMPDIR:-/tmp}/frep-mesh-open3d.$$
mkdir -p "$T" || exit 1
trap 'rm -rf "$T"' EXIT
# run from the scratch directory: a stray module in the caller's directory must not shadow
# the standard library's
if ! (cd "$T" && "$PY" -c 'import open3d') >/dev/null 2>&1; then
  echo "1..0 # SKIP Open3D is not importable by $PY (apt-get install python3-open3d)"
  exit 0
fi
cat > "$T/o3d.py" <<'PYEOF'
import sys
import open3d as o3d
m = o3d.io.read_triangle_mesh(sys.argv[1])
v = float(sys.argv[2])
ok = (len(m.triangles) > 0 and m.is_edge_manifold() and m.is_vertex_manifold()
      and not m.is_self_intersecting() and m.is_watertight())
vol = m.get_volume() if ok else float("nan")
print("triangles %d watertight %s edge-manifold %s vertex-manifold %s self-intersecting %s "
      "volume %.9g (frep %.9g)" % (len(m.triangles), m.is_watertight(), m.is_edge_manifold(),
                                   m.is_vertex_manifold(), m.is_self_intersecting(), vol, v))
sys.exit(0 if ok and abs(vol - v) <= 1e-6 * abs(v) else 1)
PYEOF
n=0
fails=0
for case in examples/csg.hf:32 examples/csg.hf:64 examples/bracket.hf:32 examples/blend.hf:32 \
            examples/twist.hf:32 examples/sphere.hf:32 tests/models/sharp/holes.hf:32; do
  hf=$srcdir/${case%%:*} g=${case##*:}
  case $hf in */examples/*) b= ;; *) b="-b 1.2" ;; esac
  n=$((n + 1))
  # shellcheck disable=SC2086
  vol=$("$FREP" mesh "$hf" $b -g "$g" -o "$T/m.off" --check -q -t 1 2>"$T/err" |
        sed -n 's/.*volume \([-0-9.e+]*\),.*/\1/p')
  if [ -n "$vol" ] && r=$(cd "$T" && "$PY" o3d.py m.off "$vol" 2>&1); then
    echo "ok $n - $(basename "$hf") -g $g in Open3D: $(echo "$r" | tail -1)"
  else
    echo "not ok $n - $(basename "$hf") -g $g in Open3D"
    { cat "$T/err"; echo "$r"; } | sed 's/^/# /'
    fails=$((fails + 1))
  fi
done
echo "1..$n"
test $fails -eq 0
