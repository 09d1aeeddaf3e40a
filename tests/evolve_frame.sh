#!/bin/sh
# evolve_frame.sh - a frame of rails joined by corner spheres around a plate (the
# InverseCSG `base`): the rails' caps and the plate's sides lie on the other rails'
# axes, inside material, so no point shows them.  frep segment constructs them
# (segment_add_constructed), frep evolve builds the union of the solids they close
# (stage_solids) and the writer reads `x1 & x2 & (rail_1 | rail_2 | slab)` as capped
# cylinders and a box: 9 solids, the program's count, and the truth's volume.  And a
# block less a bore beside a disc on a plate, their hidden faces closed by the planes
# nearest their ends (the mount).
# Prints TAP. Needs FREP.

: "${FREP:?FREP must name the frep binary}"

tmp=$(mktemp -d "${TMPDIR:-/tmp}/frep-evframe.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

. "$(dirname "$0")/tap.sh"
show() { sed 's/^/# /' "$1"; }

# A 4 x 6 x 1 plate, rails of radius 0.5 on its four edges (capped at the corners),
# spheres of radius 0.5 at the corners.  Volume: 24 + half of each rail (2.5 pi r^2 x
# 4... : 2.5 pi / 1) + a quarter of each sphere (pi / 6) = 32.37758.
cat >"$tmp/frame.hf" <<'EOF'
-- @setops minmax
-- @box -3 -4 -1 3 4 1
my_model(x[3], a[1])
{
    array lo[3], c[3];
    lo = [-2, -3, -0.5];
    plate = hfBlock(x, lo, 4, 6, 1);
    c = [0, 3, 0];
    r1 = hfCylinderX(x, c, 0.5) & (2 - x[1]) & (2 + x[1]);
    c = [0, -3, 0];
    r2 = hfCylinderX(x, c, 0.5) & (2 - x[1]) & (2 + x[1]);
    c = [2, 0, 0];
    r3 = hfCylinderY(x, c, 0.5) & (3 - x[2]) & (3 + x[2]);
    c = [-2, 0, 0];
    r4 = hfCylinderY(x, c, 0.5) & (3 - x[2]) & (3 + x[2]);
    c = [2, 3, 0];
    s1 = hfSphere(x, c, 0.5);
    c = [2, -3, 0];
    s2 = hfSphere(x, c, 0.5);
    c = [-2, 3, 0];
    s3 = hfSphere(x, c, 0.5);
    c = [-2, -3, 0];
    s4 = hfSphere(x, c, 0.5);
    my_model = plate | r1 | r2 | r3 | r4 | s1 | s2 | s3 | s4;
}
EOF
"$FREP" sample "$tmp/frame.hf" -n 6000 --seed 1 -o "$tmp/frame.xyz" -q 2>"$tmp/err"
st=$?
report $st "sample the frame"
[ $st = 0 ] || { show "$tmp/err"; echo "1..$n"; exit 1; }

"$FREP" segment "$tmp/frame.xyz" --seed 1 -o "$tmp/prims.hf" -q 2>"$tmp/err"
# Each constructed plane as its axis and offset, "+x 2" for x <= 2.
caps=$(grep 'constructed' "$tmp/prims.hf" | sed 's/.*frPlane(x, \([^)]*\)).*/\1/' |
    awk -F', ' '{ for (k = 1; k <= 3; k++) if ($k > 0.999 || $k < -0.999)
                      printf "%s%s %.3f\n", ($k > 0 ? "+" : "-"), substr("xyz", k, 1), $4 }' |
    sort | tr '\n' ' ')
[ "$caps" = "+x 2.000 +y 3.000 -x 2.000 -y 3.000 " ]
report $? "frep segment constructs the 4 caps x = +-2, y = +-3 at the rails' axes ($caps)"

nice "$FREP" evolve "$tmp/frame.xyz" -o "$tmp/m.hf" --seed 1 -q 2>"$tmp/err"
st=$?
report $st "evolve the frame"
[ $st = 0 ] || { show "$tmp/err"; echo "1..$n"; exit 1; }

grep -q '^    -- 9 solids: 1 box, 4 cylinders (4 capped), 4 spheres, 0 cones, 0 tori, 0 half-spaces$' "$tmp/m.hf"
st=$?
report $st "written as the program: a box, 4 capped rails, 4 spheres (9 solids)"
[ $st = 0 ] || show "$tmp/m.hf"

grep -q '^-- 100.00% of 6000 points within epsilon' "$tmp/m.hf" &&
    grep -Eq '% with normals within 10 degrees, (99\.[5-9][0-9]|100\.00)% both' "$tmp/m.hf"
report $? "the model explains at least 99.5% of the points ($(grep -o '[0-9.]*% both' "$tmp/m.hf"))"

vol() { "$FREP" mesh "$1" -o "$tmp/v.off" -g 128 --check 2>/dev/null | sed -n 's/.*volume \([0-9.e+-]*\).*/\1/p'; }
vt=$(vol "$tmp/frame.hf")
vm=$(vol "$tmp/m.hf")
awk -v a="$vm" -v t="$vt" 'BEGIN { e = (a - t) / t; if (e < 0) e = -e; exit !(a != "" && e < 0.001) }'
report $? "mesh volume $vm within 0.1% of the truth's $vt (analytic 32.37758)"

# The frame as a scan: 20,000 points, 0.5% noise, no normals.  The corner spheres are
# caps left by the rails (segment's second phase and reclaim), and the union of solids
# explains the points as well as the GA's tree with chamfers at the corners, in a few
# more nodes: it is taken (the old rule wanted a higher fitness, size term included,
# and wrote 13 solids: 4 uncapped rails and 9 half-spaces, no sphere).
"$FREP" sample "$tmp/frame.hf" -n 20000 --noise 0.005 --seed 1 -o "$tmp/noisy.xyz" -q &&
    cut -d' ' -f1-3 "$tmp/noisy.xyz" > "$tmp/scan.xyz" &&
    nice "$FREP" evolve "$tmp/scan.xyz" -o "$tmp/n.hf" --seed 1 -q 2>"$tmp/err"
report $? "evolve the frame scanned at 0.5% noise without normals"
grep -q '^    -- [0-9]* solids: 1 box, 4 cylinders (4 capped), 4 spheres, ' "$tmp/n.hf"
report $? "scan: the box, the 4 rails capped and the 4 corner spheres ($(grep -o -- '-- [0-9]* solids.*' "$tmp/n.hf"))"

# A block standing on a plate, bored through across its top, beside a disc, a hole
# with a floor down through both (the InverseCSG `mount_with_hole` less its frame): the
# block's bottom lies in the plate and its side x = 0 in the disc, the disc's bottom in
# the plate.  frep segment constructs the block's hidden side at its faces' extent
# (segment_close_slabs); frep evolve caps the block and the disc with the planes
# nearest their inliers' ends (the plate's top, a side of the disc) and subtracts the
# bore and the hole above its floor: 6 solids for the program's 5, the floor a
# half-space of its own (before: 8 solids, 3 of them half-spaces, the block less a
# slab of the disc's top).
cat >"$tmp/mount.hf" <<'EOF'
-- @setops minmax
-- @box -3.5 -4.5 -1.5 3.5 4.5 3
my_model(x[3], a[1])
{
    array lo[3], c[3];
    lo = [-3, -4, -1];
    plate = hfBlock(x, lo, 6, 8, 1);
    lo = [0, -1.5, -0.5];
    block = hfBlock(x, lo, 1.5, 3, 2.8);
    c = [0, 0, 2];
    bore = hfCylinderY(x, c, 1);
    c = [0, 0, 0];
    disc = hfCylinderZ(x, c, 1.5) & (1 - x[3]) & (x[3] + 0.5);
    hole = hfCylinderZ(x, c, 0.8) & (x[3] - 0.3);
    my_model = plate | ((block \ bore) | disc) \ hole;
}
EOF
"$FREP" sample "$tmp/mount.hf" -n 10000 --seed 1 -o "$tmp/mount.xyz" -q 2>"$tmp/err"
report $? "sample the mount"
"$FREP" segment "$tmp/mount.xyz" --seed 1 -o "$tmp/mprims.hf" -q 2>"$tmp/err"
side=$(grep "slab's hidden face" "$tmp/mprims.hf" | sed 's/.*frPlane(x, \([^)]*\)).*/\1/')
echo "$side" | awk -F', ' 'NF == 4 && $1 == -1 && $2 == 0 && $3 == 0 && -$4 >= 0 && -$4 < 0.5 { ok = 1 }
                          END { exit !ok }'
report $? "frep segment constructs the block's hidden side x >= 0..0.5 ($side)"
nice "$FREP" evolve "$tmp/mount.xyz" -o "$tmp/mm.hf" --seed 1 -q 2>"$tmp/err"
report $? "evolve the mount"
grep -q '^    -- 6 solids: 2 boxes, 3 cylinders (1 capped), 0 spheres, 0 cones, 0 tori, 1 half-space$' "$tmp/mm.hf" &&
    grep -Eq '^    cuts = \(cyl_bore_[12] \\ plane_z_[a-z0-9_]*\) \| cyl_bore_[12];$' "$tmp/mm.hf" &&
    grep -q '^    tree = part_1 \\ cuts;$' "$tmp/mm.hf"
st=$?
report $st "the mount written as the program: the plate, the block and the disc less the bore and the hole above its floor (6 solids)"
[ $st = 0 ] || show "$tmp/mm.hf"
grep -Eq '% with normals within 10 degrees, (99\.[5-9][0-9]|100\.00)% both' "$tmp/mm.hf"
report $? "the mount's model explains at least 99.5% of the points ($(grep -o '[0-9.]*% both' "$tmp/mm.hf"))"
vt=$(vol "$tmp/mount.hf")
vm=$(vol "$tmp/mm.hf")
awk -v a="$vm" -v t="$vt" 'BEGIN { e = (a - t) / t; if (e < 0) e = -e; exit !(a != "" && e < 0.005) }'
report $? "mount: mesh volume $vm within 0.5% of the truth's $vt"

# InverseCSG's mount as a scan: 50,000 points at 0.5% noise, no normals.  The tree
# leaves the corner spheres out (their points are 1.5% of the cloud) and the crossing
# rails make square corners, 0.29-0.30 beyond the truth at seeds 1-2 (2.3% of the
# diagonal); the writer cuts each corner beyond the rails' ends down to the sphere
# (apply_joints in evolve/canon.c): 0.03.  Measured: the truth's value at the points of
# the written model's surface beyond both rails' ends.
cat >"$tmp/mount_frame.hf" <<'EOF'
-- @setops minmax
-- @box -4 -5.5 -2 4 5.5 2.2
my_model(x[3], a[1])
{
    array lo[3], blo[3];
    lo = [-2.857143, -4.285714, -1.643];
    plate = hfBlock(x, lo, 5.714286, 8.571429, 1.428571);
    rx = (frCylinder(x, 0, 4.285714, -0.928574, 1, 0, 0, 0.714286) |
          frCylinder(x, 0, -4.285714, -0.928574, 1, 0, 0, 0.714286)) & (2.857143 - x[1]) & (2.857143 + x[1]);
    ry = (frCylinder(x, 2.857143, 0, -0.928574, 0, 1, 0, 0.714286) |
          frCylinder(x, -2.857143, 0, -0.928574, 0, 1, 0, 0.714286)) & (4.285714 - x[2]) & (4.285714 + x[2]);
    corners = frSphere(x, 2.857143, 4.285714, -0.928574, 0.714286) | frSphere(x, -2.857143, 4.285714, -0.928574, 0.714286)
            | frSphere(x, 2.857143, -4.285714, -0.928574, 0.714286) | frSphere(x, -2.857143, -4.285714, -0.928574, 0.714286);
    blo = [0, -1.642857, -0.928572];
    block = hfBlock(x, blo, 1.642857, 3.285714, 2.571429) \ frCylinder(x, 0, 0, 1.571426, 0, 1, 0, 1.071429);
    disc = frCylinder(x, 0, 0, 0, 0, 0, 1, 1.642857) & (x[3] + 0.928574) & (0.5 - x[3]);
    my_model = plate | rx | ry | corners | block | disc;
}
EOF
"$FREP" sample "$tmp/mount_frame.hf" -n 50000 --noise 0.005 --seed 2 -o "$tmp/mf.xyz" -q &&
    cut -d' ' -f1-3 "$tmp/mf.xyz" > "$tmp/mfn.xyz" &&
    nice "$FREP" evolve "$tmp/mfn.xyz" -o "$tmp/mf.hf" --seed 1 --generations 200 -q 2>"$tmp/err"
st=$?
report $st "mount's frame, 0.5% noise: sample and evolve"
[ $st = 0 ] || show "$tmp/err"
"$FREP" sample "$tmp/mf.hf" -n 20000 --seed 1 -o "$tmp/mfon.xyz" -q &&
    "$FREP" eval "$tmp/mount_frame.hf" "$tmp/mfon.xyz" > "$tmp/mfv" &&
    far=$(paste -d' ' "$tmp/mfon.xyz" "$tmp/mfv" |
          awk '{ x = $1 < 0 ? -$1 : $1; y = $2 < 0 ? -$2 : $2; v = $NF < 0 ? -$NF : $NF
                 if (x > 2.857 && y > 4.286 && v > m) m = v } END { print m + 0 }') &&
    awk -v m="$far" 'BEGIN { exit !(m > 0 && m < 0.1) }'
st=$?
report $st "mount's frame: the corners within 0.1 of the truth's spheres (farthest ${far:-?})"
[ $st = 0 ] || grep -E 'sphere|box_cut|cuts' "$tmp/mf.hf" | show /dev/stdin

tap_done
