"""Tests of the Python package frep against libfrep (tests/python.sh runs them from
make check with FREP_LIBRARY pointing at the build's libfrep.so and FREP at the
frep command).  Expected values come from numpy formulas or from the frep command's
own files (byte for byte), not from the package."""
import os
import subprocess
import warnings

import numpy as np
import pytest

import frep

SRCDIR = os.environ.get("srcdir", os.path.join(os.path.dirname(__file__), "..", ".."))
FREP = os.environ.get("FREP")
CSG = os.path.join(SRCDIR, "examples", "csg.hf")
BALL = "m(x[3], a[1]) { m = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }"
TORUS = """t(x[3], a[1]) {
  big = 1.0;  -- @free [0.5, 2]
  small = 0.3;  -- @free
  q = sqrt(x[1]*x[1] + x[2]*x[2]) - big;
  t = small*small - q*q - x[3]*x[3];
}"""


def need_frep():
    if not FREP:
        pytest.skip("FREP (the frep command) not set")


def test_version():
    v = frep.library_version()
    assert len(v.split(".")) == 3 and all(p.isdigit() for p in v.split("."))
    if FREP:
        out = subprocess.run([FREP, "--version"], capture_output=True, text=True).stdout
        assert v in out


def test_compile_error_carries_position():
    with pytest.raises(frep.FrepError) as e:
        frep.compile("m(x[3], a[1]) {\n  m = hfSphere(x, c, 1);\n}\n", name="bad.hf")
    assert "bad.hf:2:" in str(e.value)
    assert any("^" in d for d in e.value.diagnostics)


def test_params_by_name():
    p = frep.compile(TORUS)
    assert p.nparams == 3                      # a[1], big, small
    assert p.param_names == ["a[1]", "big", "small"]
    assert p.param_index("small") == 2 and p.param_index("BIG") == 1
    assert p.param_index("a[1]") == 0
    assert p.param_bounds("big") == (0.5, 2.0) and p.param_bounds("small") is None
    with pytest.raises(KeyError):
        p.param_index("s")
    x = np.array([1.0, 1.5, 0.0]); y = np.array([0.0, 0.0, 2.0]); z = np.array([0.0, 0.1, 0.0])
    for R, r in ((1.0, 0.3), (1.5, 0.2)):
        want = r * r - (np.hypot(x, y) - R) ** 2 - z ** 2
        got = p.eval(x, y, z, params={"big": R, "small": r})
        assert np.allclose(got, want, rtol=0, atol=1e-15)
    with pytest.raises(ValueError):
        p.eval(x, y, z, params=[1.0])          # a one-element vector is refused


def test_one_free_parameter():
    p = frep.compile("m(x[3], a[1]) {\n  r = 0.5;  -- @free\n  m = r - x[1];\n}\n")
    assert p.nparams == 2 and p.param_index("r") == 1
    assert p.eval([0.25], [0], [0], params={"r": 2.0})[0] == 1.75


def test_eval_and_grad_against_numpy():
    p = frep.compile(TORUS)
    rng = np.random.default_rng(5)
    pts = rng.uniform(-2, 2, size=(10000, 3))
    x, y, z = (np.ascontiguousarray(pts[:, k]) for k in range(3))
    q = np.hypot(x, y) - 1.0
    want = 0.09 - q * q - z * z
    assert np.allclose(p.eval(x, y, z), want, rtol=0, atol=1e-13)
    assert np.allclose(p.eval(pts), want, rtol=0, atol=1e-13)   # (N, 3) form
    out = np.empty(len(x))
    assert p.eval(x, y, z, out=out) is out
    f, g = p.grad(x, y, z)
    rho = np.hypot(x, y)
    want_g = np.stack([-2 * q * x / rho, -2 * q * y / rho, -2 * z], axis=1)
    assert g.shape == (10000, 3) and np.allclose(g, want_g, rtol=1e-12, atol=1e-12)
    # results do not depend on the thread count
    assert np.array_equal(p.eval(x, y, z, threads=1), p.eval(x, y, z, threads=2))


def test_runtime_errors_warn_and_give_nan():
    p = frep.compile("m(x[3], a[1]) {\n  m = sqrt(x[1]);\n}\n", name="s.hf")
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        f = p.eval(np.array([-1.0, 4.0]), np.zeros(2), np.zeros(2))
    assert np.isnan(f[0]) and f[1] == 2.0
    assert any("s.hf:2:" in str(m.message) for m in w)


def test_interval_encloses():
    p = frep.compile(BALL)
    lo, hi = p.interval((0.5, -0.3, 0.2, 1.2, 0.4, 0.9))
    rng = np.random.default_rng(1)
    pts = rng.uniform((0.5, -0.3, 0.2), (1.2, 0.4, 0.9), size=(5000, 3))
    f = p.eval(pts)
    assert lo <= f.min() and f.max() <= hi and lo < 0 < hi
    assert p.interval((2, 2, 2, 3, 3, 3))[1] < 0



def test_grid_summary():
    p = frep.compile(BALL)
    g = p.grid_summary(n=41, box=1.2, threads=2)
    # the ball's grid points counted with numpy
    t = np.linspace(-1.2, 1.2, 41)
    x, y, z = np.meshgrid(t, t, t, indexing="ij")
    f = 1 - x * x - y * y - z * z
    assert g["points"] == 41 ** 3 and g["inside"] == np.count_nonzero(f >= 0)
    assert g["nans"] == 0 and g["errors"] == 0 and g["box"] == (-1.2,) * 3 + (1.2,) * 3
    assert g["min"] == pytest.approx(f.min()) and g["max"] == pytest.approx(f.max())
    assert g["sum"] == pytest.approx(f.sum())
    assert p.grid_summary(n=41, box=1.2, prune=False, threads=1)["inside"] == g["inside"]
    with pytest.raises(frep.FrepError):
        p.grid_summary(n=1)
    if FREP:
        out = subprocess.run([FREP, "eval", "--grid", "33", CSG], capture_output=True,
                             text=True).stdout
        c = frep.compile_file(CSG).grid_summary(n=33)
        assert "inside    %d " % c["inside"] in out
        assert "values    min %.9g  max %.9g  sum %.9g" % (c["min"], c["max"], c["sum"]) in out


def test_print_source():
    with open(CSG) as f:
        text = f.read()
    out = frep.print_source(text, name=CSG)
    # the canonical source is a fixed point and compiles to a program of the same size
    assert frep.print_source(out) == out
    assert frep.compile(out).size == frep.compile(text).size
    if FREP:
        assert out == subprocess.run([FREP, "print", CSG], capture_output=True,
                                     text=True).stdout
    with pytest.raises(frep.FrepError) as e:
        frep.print_source("m(x[3], a[1]) { m = ; }", name="bad.hf")
    assert "bad.hf:1:" in str(e.value)


def test_mesh_closed_and_volume():
    p = frep.compile(BALL)
    m = p.mesh(grid=32, box=1.5)
    assert m.vertices.shape[1] == 3 and m.triangles.shape[1] == 3
    assert m.normals.shape == m.vertices.shape
    assert m.triangles.max() < len(m.vertices)
    c = m.check(self_intersections=True)
    assert all(c[k] == 0 for k in c if k not in ("volume", "area"))
    assert abs(c["volume"] - 4 / 3 * np.pi) < 0.05
    # the signed volume again, from the numpy arrays alone (divergence theorem)
    v = m.vertices[m.triangles]
    vol = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6
    assert abs(vol - c["volume"]) < 1e-9
    assert not m.info["touches_box"] and m.info["grid"] == 32
    # a mesh made from arrays
    m2 = frep.Mesh(m.vertices, m.triangles)
    assert np.array_equal(m2.vertices, m.vertices) and m2.normals is None


def test_mesh_info_matches_the_library():
    # the ctypes mirror of frep_mesh_info: counts, each step's clock, the flag last
    m = frep.compile(BALL).mesh(grid=32, box=1.5)
    i = m.info
    steps = [i[k] for k in ("octree_seconds", "contour_seconds", "quads_seconds",
                            "assembly_seconds", "settle_seconds")]
    assert i["grid"] == 32 and i["blocks"] > 0 and i["blocks"] <= i["blocks_total"]
    assert all(t >= 0 for t in steps) and 0 < sum(steps) <= i["seconds"]
    assert i["interrupted"] == 0


def test_mesh_views_outlive_mesh():
    v = frep.compile(BALL).mesh(grid=8, box=1.5).vertices
    assert np.isfinite(v).all() and abs(np.linalg.norm(v, axis=1).mean() - 1) < 0.05


@pytest.mark.parametrize("ext,ascii", [("stl", False), ("stl", True), ("obj", False),
                                       ("ply", False), ("off", False)])
def test_mesh_file_same_as_command(tmp_path, ext, ascii):
    need_frep()
    cli, api = tmp_path / ("cli." + ext), tmp_path / ("api." + ext)
    subprocess.run([FREP, "mesh", CSG, "-g", "32", "-o", str(cli)] + (["--ascii"] if ascii else []),
                   check=True, capture_output=True)
    frep.compile_file(CSG).mesh(grid=32).write(api, ascii=ascii)
    assert cli.read_bytes() == api.read_bytes()


@pytest.mark.parametrize("ext", ["xyz", "ply"])
def test_sample_same_as_command(tmp_path, ext):
    need_frep()
    cli, api = tmp_path / ("cli." + ext), tmp_path / ("api." + ext)
    subprocess.run([FREP, "sample", CSG, "-n", "1500", "--seed", "11", "--noise", "0.001",
                    "-o", str(cli)], check=True, capture_output=True)
    c = frep.compile_file(CSG).sample(1500, seed=11, noise=0.001)
    c.write(api)
    assert cli.read_bytes() == api.read_bytes()
    assert c.points.shape == (1500, 3) and c.normals.shape == (1500, 3)


def test_sample_on_surface():
    p = frep.compile(BALL)
    c = p.sample(2000, seed=3, box=1.5)
    r = np.linalg.norm(c.points, axis=1)
    assert np.abs(r - 1).max() < 1e-6
    assert np.allclose(c.normals, c.points / r[:, None], atol=1e-6)   # outward unit normals
    c2 = p.sample(2000, seed=3, box=1.5, threads=1)
    assert np.array_equal(c.points, c2.points)


def test_cloud_roundtrip_and_errors(tmp_path):
    pts = np.array([[0, 0.1, 1e-300], [1.5, 0.2, 5], [-2, 0.3, 6]])
    nrm = np.eye(3)
    for ext in ("xyz", "ply"):
        frep.Cloud(pts, nrm).write(tmp_path / ("c." + ext))
        r = frep.read_cloud(tmp_path / ("c." + ext))
        assert np.array_equal(r.points, pts) and np.array_equal(r.normals, nrm)
    (tmp_path / "bad.xyz").write_text("0 0 0\n1 2 3 4 5\n")
    with pytest.raises(frep.FrepError) as e:
        frep.read_cloud(tmp_path / "bad.xyz")
    assert "bad.xyz:2:" in str(e.value)


def test_open3d_helper():
    o3d = pytest.importorskip("open3d")
    m = frep.compile(BALL).mesh(grid=16, box=1.5)
    t = m.to_open3d()
    assert isinstance(t, o3d.geometry.TriangleMesh)
    assert len(t.vertices) == len(m.vertices) and t.is_watertight()


def test_segment_same_as_command(tmp_path):
    need_frep()
    model = os.path.join(SRCDIR, "tests", "models", "segment_box.hf")
    xyz = tmp_path / "box.xyz"
    subprocess.run([FREP, "sample", model, "-n", "5000", "--seed", "4", "-q", "-o", str(xyz)],
                   check=True)
    subprocess.run([FREP, "segment", str(xyz), "--seed", "2", "-q", "-o",
                    str(tmp_path / "cli.fit"), "--labels", str(tmp_path / "cli.labels")],
                   check=True)
    calls = []
    c = frep.read_cloud(xyz)
    s = c.segment(seed=2, progress=lambda *a: calls.append(a))
    s.write(tmp_path / "api.fit")
    assert (tmp_path / "cli.fit").read_bytes() == (tmp_path / "api.fit").read_bytes()
    want = np.loadtxt(tmp_path / "cli.labels", dtype=np.int64) - 1
    assert np.array_equal(s.labels, want)
    assert s.nfitted >= 6 and not s.interrupted and calls and calls[0][0] == "detect" and \
        {a[0] for a in calls} <= {"detect", "merge"}


def test_segment_cancel():
    model = frep.compile_file(os.path.join(SRCDIR, "tests", "models", "segment_box.hf"))
    c = model.sample(4000, seed=1)
    polls = []
    s = c.segment(seed=1, cancel=lambda: polls.append(1) or len(polls) >= 3)
    assert s.interrupted and len(polls) == 3 and s.nfitted < 6


def test_normals_same_as_command(tmp_path):
    need_frep()
    model = os.path.join(SRCDIR, "tests", "models", "segment_box.hf")
    full = frep.compile_file(model).sample(3000, seed=6, noise=0.001)
    bare = tmp_path / "bare.xyz"
    frep.Cloud(full.points).write(bare)
    for knn in (0, 20):
        out = tmp_path / ("cli%d.xyz" % knn)
        subprocess.run([FREP, "normals", str(bare), "-q", "-o", str(out)] +
                       (["--knn", str(knn)] if knn else []), check=True)
        want = np.loadtxt(out)
        n, info = frep.normals(np.loadtxt(bare), knn=knn, threads=2, info=True)
        assert n.shape == (3000, 3) and n.dtype == np.float64
        # the command prints %.17g: exact
        assert np.array_equal(n, want[:, 3:]) and np.array_equal(np.loadtxt(bare), want[:, :3])
        assert info["knn"] == (knn or info["knn"]) and info["knn"] >= 3 and info["spacing"] > 0
    # unit length; all outward (a step along the normal leaves the solid: at an edge
    # of the box either face's normal is right, at 90 degrees to the sampler's), and
    # within 60 degrees of the sampler's exact normals but at the box's edges
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0)
    prog = frep.compile_file(model)
    p = full.points
    assert np.all(prog.eval(p + 0.02 * n) < prog.eval(p - 0.02 * n))
    dots = np.sum(n * full.normals, axis=1)
    assert np.mean(dots > 0.5) > 0.97


def test_normals_in_place_and_errors():
    c = frep.Cloud(np.random.default_rng(1).normal(size=(500, 3)))
    assert c.normals is None
    info = c.estimate_normals(knn=16)
    assert info["knn"] == 16 and c.normals.shape == (500, 3)
    with pytest.raises(frep.FrepError, match="knn 2"):
        c.estimate_normals(knn=2)
    with pytest.raises(frep.FrepError, match="one line"):
        frep.normals([[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3]])
    with pytest.raises(frep.FrepError, match="too few points"):
        frep.normals([[0, 0, 0], [1, 0, 0]])


def test_segmentation_info_and_prims():
    model = frep.compile_file(os.path.join(SRCDIR, "tests", "models", "segment_box.hf"))
    bare = frep.Cloud(model.sample(4000, seed=2).points)
    s = bare.segment(seed=2)
    assert s.info["normals_estimated"] and bare.normals is not None
    assert s.info["npoints"] == 4000 and s.info["nprims"] == s.nprims
    prims = s.prims()
    assert len(prims) == s.nprims and sum(not q["separating"] for q in prims) == s.nfitted
    assert all(q["type"] in frep.PRIM_TYPES for q in prims)
    fitted = [q for q in prims if not q["separating"]]
    # a primitive's support is the points labelled with it
    counts = np.bincount(s.labels[s.labels >= 0], minlength=s.nfitted)
    assert list(counts) == [q["support"] for q in fitted]
    planes = [q for q in fitted if q["type"] == "plane"]
    assert all(abs(np.linalg.norm(q["p"]) - 1) < 1e-9 for q in planes)


SPHERE_TEMPLATE = """-- a sphere of unknown centre and radius
my_model(x[3], a[1]) {
  cx = 0;     -- @free [-1, 1]
  r = 1;      -- @free [0.2, 3]
  my_model = r*r - (x[1]-cx)*(x[1]-cx) - x[2]*x[2] - x[3]*x[3];
}
"""
SPHERE_TRUTH = """my_model(x[3], a[1]) {
  my_model = 1.44 - (x[1]-0.3)*(x[1]-0.3) - x[2]*x[2] - x[3]*x[3];
}
-- @box -2 -2 -2 2 2 2
"""


def test_fit_recovers_and_same_as_command(tmp_path):
    tmpl = tmp_path / "sphere.hf"
    tmpl.write_text(SPHERE_TEMPLATE)
    cloud = frep.compile(SPHERE_TRUTH).sample(1500, seed=4, noise=0.001)
    xyz = tmp_path / "sphere.xyz"
    cloud.write(xyz)
    calls = []
    f = frep.fit_file(tmpl, frep.read_cloud(xyz), seed=7, progress=calls.append)
    # the truth: centre 0.3 on x, radius 1.2 (sqrt 1.44)
    assert abs(f.params["cx"] - 0.3) < 0.005 and abs(f.params["r"] - 1.2) < 0.005
    assert [p["name"] for p in f.parameters] == ["cx", "r"]
    assert f.parameters[1]["lo"] == 0.2 and f.parameters[1]["hi"] == 3
    assert f.converged and not f.interrupted and f.verdict.startswith("good")
    # the noise: 0.001 of the box diagonal 4 sqrt(3), 0.0069
    assert f.npoints == 1500 and 0.5 * 0.0069 < f.rms < 1.5 * 0.0069
    assert calls and {"phase", "best", "elapsed"} <= set(calls[0])
    # the vector evaluates like the fitted template: f = 0 near the cloud
    p = frep.compile(SPHERE_TEMPLATE)
    assert np.allclose(f.values[1:], [f.params["cx"], f.params["r"]])
    d = p.eval(cloud.x, cloud.y, cloud.z, params=f.values)
    cx, r = f.params["cx"], f.params["r"]
    want = r * r - (cloud.x - cx) ** 2 - cloud.y ** 2 - cloud.z ** 2
    assert np.allclose(d, want, rtol=0, atol=1e-12)
    assert "-- @box " in f.text and abs(f.program().eval([1.5], [0], [0])[0]) < 0.01
    if FREP:
        subprocess.run([FREP, "fit", str(tmpl), str(xyz), "--seed", "7", "-q", "-o",
                        str(tmp_path / "cli.hf")], check=True)
        f.write(tmp_path / "api.hf")
        assert (tmp_path / "cli.hf").read_bytes() == (tmp_path / "api.hf").read_bytes()


def test_fit_a_array_and_cancel():
    cloud = frep.compile(SPHERE_TRUTH).sample(1000, seed=3)
    tmpl = ("my_model(x[3], a[2]) {\n"
            "  my_model = a[2]*a[2] - (x[1]-a[1])*(x[1]-a[1]) - x[2]*x[2] - x[3]*x[3];\n}\n")
    f = frep.fit(tmpl, cloud.points, a=[0, 1], bounds=[(-1, 1), (0.2, 3)], method="qn")
    assert np.allclose(f.values, [0.3, 1.2], atol=0.005) and "-- @params " in f.text
    polls = []
    f = frep.fit(SPHERE_TEMPLATE, cloud, cancel=lambda: polls.append(1) or True)
    assert f.interrupted and f.status == "interrupted" and len(polls) >= 1
    with pytest.raises(frep.FrepError) as e:
        frep.fit("m(x[3], a[1]) { m = 1 - x[1]; }", cloud)
    assert "no free parameters" in str(e.value)
    with pytest.raises(ValueError):
        frep.fit(SPHERE_TEMPLATE, cloud, method="newton")


def test_evolve_same_as_command(tmp_path):
    need_frep()
    model = os.path.join(SRCDIR, "tests", "models", "segment_box.hf")
    xyz, fit = tmp_path / "ev.xyz", tmp_path / "ev.fit"
    subprocess.run([FREP, "sample", model, "-n", "3000", "--seed", "6", "-q", "-o", str(xyz)],
                   check=True)
    subprocess.run([FREP, "segment", str(xyz), "--seed", "2", "-q", "-o", str(fit)], check=True)
    args = ["evolve", str(xyz), "-p", str(fit), "--seed", "3", "--population", "60",
            "--generations", "40", "-q", "-o", str(tmp_path / "cli.hf")]
    subprocess.run([FREP] + args, check=True)
    calls = []
    prims = frep.read_prims(fit)
    assert prims.nprims >= 6 and prims.labels.shape == (0,)
    e = frep.read_cloud(xyz).evolve(prims, seed=3, population=60, generations=40,
                                    progress=calls.append)
    assert e.tree_size >= 11 and e.explained > 2900 and not e.interrupted
    assert calls and {"generation", "best_fitness", "tree_size"} <= set(calls[0])
    e.write(tmp_path / "api.hf", command="frep " + " ".join(args), cloud_name=str(xyz))
    cli = (tmp_path / "cli.hf").read_text().splitlines()
    api = (tmp_path / "api.hf").read_text().splitlines()
    # the same model but the line with the run's seconds
    assert len(cli) == len(api) and len(cli) > 10
    assert [a for a, b in zip(cli, api) if a != b and " generations, " not in a] == []
    e.write_dot(tmp_path / "api.dot")
    assert (tmp_path / "api.dot").read_text().startswith("digraph")


def test_evolve_cancel():
    model = frep.compile_file(os.path.join(SRCDIR, "tests", "models", "segment_box.hf"))
    c = model.sample(2500, seed=1)
    s = c.segment(seed=1)
    polls = []
    e = c.evolve(s, partition=False, stagnation=10 ** 6, generations=10 ** 6,
                 cancel=lambda: polls.append(1) or len(polls) >= 4)
    assert e.interrupted and len(polls) == 4 and e.generations <= 5 and e.tree_size > 0


BLOCK = """-- @setops minmax
-- @box -1.5 -1.5 -1 1.5 1.5 1
my_model(x[3], a[1])
{
    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &
               frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);
}
"""


def test_evolve_residual_trace(tmp_path):
    # a block with a hole: the block as the base, the hole evolved from the points it
    # does not explain; the trace's lines as frep evolve --trace writes them
    hole = frep.compile(BLOCK.replace("my_model = frPlane", "blk = frPlane").replace(
        "frPlane(x, 0, 0, -1, 0.5);",
        "frPlane(x, 0, 0, -1, 0.5);\n    my_model = blk \\ frCylinder(x, 0.2, 0.1, 0, 0, 0, 1, 0.4);"))
    c = hole.sample(3000, seed=1)
    base = frep.EvolveBase(frep.compile(BLOCK, name="block.hf"))
    assert base.setops == "minmax"
    lines, phases = [], set()
    e = c.evolve(base=base, seed=1, trace=lines.append,
                 progress=lambda p: phases.add(frep.EVOLVE_PHASES[p["phase"]]))
    assert 2000 < e.base_explained < 3000 and e.explained > 2950
    assert {"segment", "search"} <= phases
    assert lines[0] == "# frep evolve trace, seed 1\n" and lines[-1].startswith("# end:")
    text = e.model(cloud_name="hole.xyz")
    assert "base_model(x, a)" in text and "frCylinder" in text
    e.write(tmp_path / "r.hf", cloud_name="hole.xyz")
    assert (tmp_path / "r.hf").read_text() == text
    assert e.dot().startswith("digraph")
    with pytest.raises(frep.FrepError):
        frep.EvolveBase(frep.compile("m(x[2], a[1]) { m = 1 - x[1]*x[1]; }"))


def test_render_same_as_command(tmp_path):
    p = frep.compile_file(CSG)
    m = p.mesh(grid=32)
    c = p.sample(500, seed=2, noise=0.01)
    img = m.render(96, 64, points=c, program=p)
    assert img.pixels.shape == (64, 96, 3) and img.pixels.dtype == np.uint8
    assert img.info["npoints"] == 500 and img.info["ntris"] == len(m.triangles)
    assert img.pixels.std() > 0                       # not a blank picture
    if FREP:
        c.write(tmp_path / "c.xyz")
        subprocess.run([FREP, "render", CSG, "-g", "32", "--size", "96x64", "--points",
                        str(tmp_path / "c.xyz"), "-q", "-o", str(tmp_path / "cli.png")],
                       check=True)
        c2 = frep.read_cloud(tmp_path / "c.xyz")
        m.render(96, 64, points=c2, program=p).write_png(tmp_path / "api.png")
        assert (tmp_path / "cli.png").read_bytes() == (tmp_path / "api.png").read_bytes()
    with pytest.raises(frep.FrepError):
        m.render(view="upside")


def test_mesh_colors_same_as_command(tmp_path):
    need_frep()
    path = os.path.join(SRCDIR, "tests", "models", "color_sphere.hf")
    cli = tmp_path / "cli.ply"
    subprocess.run([FREP, "mesh", path, "-b", "1", "-g", "32", "--ascii", "-o", str(cli)],
                   check=True, capture_output=True)
    lines = cli.read_text().splitlines()
    nv = int(next(ln for ln in lines if ln.startswith("element vertex")).split()[2])
    start = lines.index("end_header") + 1
    want = np.array([[int(v) for v in ln.split()[6:9]] for ln in lines[start:start + nv]])
    model = frep.compile_file(path)
    m = model.mesh(grid=32, box=1)
    rgb = model.colors(m, cell=2 / 32)
    assert rgb.shape == (nv, 3) and rgb.dtype == np.uint8
    assert np.array_equal(rgb, want)
    assert frep.compile(BALL).colors(frep.compile(BALL).mesh(grid=8, box=1.5), cell=3 / 8) is None


def test_option_structs_match_the_library():
    # Each *_options_init memsets the C struct: a Python mirror shorter than the C one
    # (a field added in frep.h but not here) would see the guard bytes after it cleared.
    import ctypes
    lib = frep._L()
    for name, cls in (("compile", frep._CompileOptions), ("mesh", frep._MeshOptions),
                      ("sample", frep._SampleOptions), ("segment", frep._SegmentOptions),
                      ("fit", frep._FitOptions), ("evolve", frep._EvolveOptions),
                      ("render", frep._RenderOptions), ("normals", frep._NormalsOptions),
                      ("scad", frep._ScadOptions)):
        size = ctypes.sizeof(cls)
        buf = (ctypes.c_ubyte * (size + 64))(*([0xAB] * (size + 64)))
        getattr(lib, "frep_%s_options_init" % name)(ctypes.cast(buf, ctypes.POINTER(cls)))
        assert bytes(buf[size:]) == b"\xab" * 64, name
    size = ctypes.sizeof(frep._ViewScene)
    buf = (ctypes.c_ubyte * (size + 64))(*([0xAB] * (size + 64)))
    lib.frep_view_scene_init(ctypes.cast(buf, ctypes.POINTER(frep._ViewScene)))
    assert bytes(buf[size:]) == b"\xab" * 64 and bytes(buf[:size]) == b"\0" * size


def test_param_used():
    p = frep.compile("m(x[3], a[3]) {\n  r = 1;  -- @free\n  q = 2;  -- @free\n"
                     "  m = r + a[2] - x[1];\n}\n")
    assert [p.param_used(n) for n in ("a[1]", "a[2]", "a[3]", "r", "q")] == \
        [False, True, False, True, False]


def test_fit_names_match_the_library():
    lib = frep._L()
    for table, fn in ((frep.FIT_METHODS, lib.frep_fit_method_name),
                      (frep.FIT_OBJECTIVES, lib.frep_fit_objective_name),
                      (frep.FIT_LOSSES, lib.frep_fit_loss_name)):
        assert tuple(fn(i).decode() for i in range(len(table))) == table
        assert fn(len(table)) is None


def test_export_scad_same_as_command(tmp_path):
    with open(CSG) as f:
        text = f.read()
    scad = frep.export_scad(text, name=CSG)
    assert "module my_model()" in scad and "difference()" in scad
    assert "$fn = 12;" in frep.export_scad(text, name=CSG, fn=12)
    if FREP:
        out = tmp_path / "cli.scad"
        subprocess.run([FREP, "export", CSG, "-q", "-o", str(out)], check=True)
        assert out.read_text() == scad
    with pytest.raises(frep.FrepError) as e:
        frep.export_scad("m(x[3], a[1]) {\n  m = x[1]^2 - x[2];\n}\n", name="q.hf")
    assert "q.hf:2:" in str(e.value)
    with pytest.raises(frep.FrepError):
        frep.export_scad(text, fn=2)


def test_distances_against_model_and_mesh():
    p = frep.compile_file(CSG)
    m = p.mesh(grid=32)
    c = p.sample(400, seed=3, noise=0.005)
    dm = frep.distances(c, m, program=p)
    dt = frep.distances(c, m)
    assert dm["point"].shape == (400,) and dm["vertex"].shape == (len(m.vertices),)
    # the model's first-order distance against numpy's: f / |grad f|
    x, y, z = c.points[:, 0], c.points[:, 1], c.points[:, 2]
    f, g = p.grad(x, y, z)
    assert np.allclose(dm["point"], f / np.linalg.norm(g, axis=1), rtol=1e-9, atol=1e-12)
    assert np.median(np.abs(dm["point"] - dt["point"])) < 0.01
    # each vertex's distance to the nearest point, by brute force
    v = m.vertices[:50]
    near = np.sqrt(((v[:, None, :] - c.points[None, :, :]) ** 2).sum(axis=2)).min(axis=1)
    assert np.allclose(dm["vertex"][:50], near, rtol=1e-12)
    assert np.array_equal(dm["vertex"], dt["vertex"])
    assert dm["point_scale"] > 0 and dm["vertex_scale"] > 0
    with pytest.raises(frep.FrepError):
        frep.distances(c, frep.Mesh(np.zeros((0, 3)), np.zeros((0, 3))))


def test_view_page_same_as_command(tmp_path):
    p = frep.compile_file(CSG)
    m = p.mesh(grid=24)
    c = p.sample(300, seed=4, noise=0.01)
    page = frep.view_page(m, c, program=p, name="csg.hf")
    assert page.startswith("<!DOCTYPE html>") or "<html" in page[:200]
    assert '"points":{"n":300,' in page and '"name":"csg.hf"' in page
    assert '"source":null' not in page and '"source":"' in page
    if FREP:
        m.write(tmp_path / "m.off")
        c.write(tmp_path / "c.xyz")
        subprocess.run([FREP, "view", str(tmp_path / "m.off"), "--points",
                        str(tmp_path / "c.xyz"), "-q", "-o", str(tmp_path / "cli.html")],
                       check=True)
        page = frep.view_page(frep.read_mesh(tmp_path / "m.off"),
                              frep.read_cloud(tmp_path / "c.xyz"), name=str(tmp_path / "m.off"))
        assert (tmp_path / "cli.html").read_text() == page
