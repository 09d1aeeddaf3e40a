/* test_api.c - the public API alone (frep.h; linked against the installed library's
 * libfrep.la, so nothing internal is reachable): the version, free parameters
 * addressed by name, interval enclosures, grid summaries, canonical source, clouds,
 * meshes and sampling, errors and warnings through the callback, and files and
 * figures identical to the frep command's (run as $FREP) for the same options and
 * seed.
 */
#include "config.h"

#include "frep.h"
#include "tap.h"

#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

/* Diagnostics seen: the count per severity and the last message. */
typedef struct seen {
    int errors, warnings;
    char last[1024];
    int positioned;     /* diagnostics with a source line */
} seen;

static void collect(void *user, const frep_diag *d)
{
    seen *s = user;
    if (d->severity == FREP_ERROR) s->errors++;
    if (d->severity == FREP_WARNING) s->warnings++;
    if (d->line > 0) s->positioned++;
    snprintf(s->last, sizeof s->last, "%s", d->message);
}

static frep_program *compile(const char *src, seen *s)
{
    return frep_compile("t.hf", src, strlen(src), NULL, collect, s);
}

static char tmpdir[256];

static const char *tmp(const char *name)
{
    static char path[4][512];
    static int k;
    k = (k + 1) % 4;
    snprintf(path[k], sizeof path[k], "%s/%s", tmpdir, name);
    return path[k];
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f) return;
    fputs(text, f);
    fclose(f);
}

/* Whether two files hold the same bytes (and exist). */
static int same_file(const char *a, const char *b)
{
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int ca = getc(fa), cb = getc(fb);
        if (ca != cb) same = 0;
        if (ca == EOF || cb == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

static void test_version(void)
{
    is_str(frep_version(), FREP_VERSION_STRING, "frep_version() is the header's version");
    is_str(frep_version(), PACKAGE_VERSION, "and the package's");
    char v[32];
    snprintf(v, sizeof v, "%d.%d.%d", FREP_VERSION_MAJOR, FREP_VERSION_MINOR, FREP_VERSION_PATCH);
    is_str(v, FREP_VERSION_STRING, "MAJOR.MINOR.PATCH macros agree with the string");
    ok(FREP_VERSION_NUMBER == FREP_VERSION_MAJOR * 10000 + FREP_VERSION_MINOR * 100 +
                                  FREP_VERSION_PATCH, "FREP_VERSION_NUMBER");
}

/* The issue's case: one `-- @free r` in a model with the usual a[1]. */
static void test_params(void)
{
    seen s = { 0 };
    frep_program *p = compile("my_model(x[3], a[1]) {\n"
                              "  r = 0.5;  -- @free [0.1, 3]\n"
                              "  my_model = r*r - x[1]*x[1] - x[2]*x[2] - x[3]*x[3];\n}\n", &s);
    ok(p != NULL, "model with one named free parameter compiles");
    if (!p) return;
    is_int(frep_program_nparams(p), 2, "the vector holds a[1] and r");
    is_int(frep_program_na(p), 1, "one element of a[]");
    is_int(frep_program_nfree(p), 1, "one named parameter");
    size_t ir = 99, ia = 99, ix = 99;
    ok(frep_program_param_index(p, "r", &ir) == 0 && ir == 1, "r is at index 1");
    ok(frep_program_param_index(p, "R", &ix) == 0 && ix == 1, "names are case-insensitive");
    ok(frep_program_param_index(p, "a[1]", &ia) == 0 && ia == 0, "a[1] is at index 0");
    ok(frep_program_param_index(p, "a[2]", &ix) != 0, "a[2] is not a parameter (a[1] only)");
    ok(frep_program_param_index(p, "a[0]", &ix) != 0, "a[0] is not either (1-based)");
    ok(frep_program_param_index(p, "q", &ix) != 0, "an unknown name fails");
    double lo, hi;
    ok(frep_program_param_bounds(p, ir, &lo, &hi) == 1 && lo == 0.1 && hi == 3, "r's bounds");
    /* exactly nparams doubles on the heap: reading past it is caught by ASan */
    double one[1] = { 7 };
    ok(frep_program_param_values(p, one, 1) == -1 && one[0] == 7,
       "a one-element vector is refused, untouched");
    double *v = malloc(frep_program_nparams(p) * sizeof *v);
    ok(v && frep_program_param_values(p, v, frep_program_nparams(p)) == 0 && v[0] == 0 &&
           v[1] == 0.5, "param_values fills [a[1], r] = [0, 0.5]");
    if (v) {
        v[ir] = 2;
        double x = 0.5, y = 0, z = 0, f = 0;
        frep_scratch *sc = frep_scratch_new(p);
        ok(sc && frep_eval(p, sc, 1, &x, &y, &z, v, &f) == 0 && f == 4 - 0.25,
           "evaluation with r = 2 set by name: f = r^2 - |x|^2");
        frep_scratch_free(sc);
    }
    free(v);
    frep_program_free(p);

    /* a[] read by the model and a named parameter: a[1], a[2], then r */
    p = compile("m(x[3], a[2]) {\n  r = 1.5;  -- @free\n  m = r - a[2] * x[1];\n}\n", &s);
    size_t i2 = 99;
    ok(p && frep_program_nparams(p) == 3 && frep_program_na(p) == 2 &&
           frep_program_nfree(p) == 1 && frep_program_param_index(p, "a[2]", &i2) == 0 &&
           i2 == 1 && frep_program_param_index(p, "r", &ir) == 0 && ir == 2,
       "m(x[3], a[2]) with r: [a[1], a[2], r]");
    if (p) {
        double pv[3] = { 0, 2, 3 }, x = 1, y = 0, z = 0, f = 0;
        ok(frep_eval_par(p, 1, &x, &y, &z, pv, &f, 1, NULL) == 0 && f == 1,
           "a[2] = 2 and r = 3 by index: f = r - a[2] x = 1");
        frep_program_free(p);
    }
}

static void test_interval(void)
{
    seen s = { 0 };
    frep_program *p = compile("m(x[3], a[1]) { m = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }", &s);
    frep_interval_scratch *is = p ? frep_interval_scratch_new(p) : NULL;
    ok(is != NULL, "interval scratch");
    if (!is) {
        frep_program_free(p);
        return;
    }
    double lo = 0, hi = 0;
    const double far[6] = { 2, 2, 2, 3, 3, 3 };
    int rc = frep_eval_interval(p, is, far, NULL, &lo, &hi);
    ok(rc == 0 && hi < 0, "a box away from the unit ball is outside (hi %g < 0)", hi);
    const double center[6] = { -0.1, -0.1, -0.1, 0.1, 0.1, 0.1 };
    rc = frep_eval_interval(p, is, center, NULL, &lo, &hi);
    ok(rc == 0 && lo > 0, "a box at the centre is inside (lo %g > 0)", lo);
    /* the enclosure holds the point values of a box across the surface */
    const double across[6] = { 0.5, -0.3, 0.2, 1.2, 0.4, 0.9 };
    int inside = frep_eval_interval(p, is, across, NULL, &lo, &hi) == 0;
    frep_scratch *sc = frep_scratch_new(p);
    for (int i = 0; i < 1000 && sc && inside; i++) {
        double t = i / 999.0;
        double x = across[0] + t * (across[3] - across[0]);
        double y = across[1] + (1 - t) * (across[4] - across[1]);
        double z = across[2] + (i % 7) / 6.0 * (across[5] - across[2]);
        double f;
        if (frep_eval(p, sc, 1, &x, &y, &z, NULL, &f) != 0 || f < lo || f > hi) inside = 0;
    }
    ok(inside && lo < 0 && hi > 0, "enclosure [%g, %g] holds 1000 point values", lo, hi);
    frep_scratch_free(sc);
    frep_interval_scratch_free(is);
    frep_program_free(p);
}

static void test_cloud(void)
{
    seen s = { 0 };
    double x[3] = { 0, 1.5, -2 }, y[3] = { 0.1, 0.2, 0.3 }, z[3] = { 1e-300, 5, 6 };
    double nx[3] = { 1, 0, 0 }, ny[3] = { 0, 1, 0 }, nz[3] = { 0, 0, 1 };
    frep_cloud *c = frep_cloud_new(3, x, y, z, nx, ny, nz, collect, &s);
    ok(c && frep_cloud_size(c) == 3 && frep_cloud_has_normals(c), "cloud of 3 with normals");
    ok(c && frep_cloud_write(c, tmp("c.xyz"), collect, &s) == 0 &&
           frep_cloud_write(c, tmp("c.ply"), collect, &s) == 0, "written as .xyz and .ply");
    const char *names[2] = { "c.xyz", "c.ply" };
    for (int k = 0; k < 2; k++) {
        frep_cloud *r = frep_cloud_read(tmp(names[k]), collect, &s);
        const double *rx, *ry, *rz, *rnx, *rny, *rnz;
        int same = r && frep_cloud_size(r) == 3 && frep_cloud_has_normals(r);
        if (same) {
            frep_cloud_arrays(r, &rx, &ry, &rz, &rnx, &rny, &rnz);
            for (int i = 0; i < 3; i++)
                same &= rx[i] == x[i] && ry[i] == y[i] && rz[i] == z[i] && rnx[i] == nx[i] &&
                        rny[i] == ny[i] && rnz[i] == nz[i];
        }
        ok(same, "%s read back exactly", names[k]);
        frep_cloud_free(r);
    }
    frep_cloud_free(c);
    c = frep_cloud_new(2, x, y, z, NULL, NULL, NULL, collect, &s);
    const double *pnx = x;
    if (c) frep_cloud_arrays(c, NULL, NULL, NULL, &pnx, NULL, NULL);
    ok(c && !frep_cloud_has_normals(c) && pnx == NULL, "a cloud without normals");
    frep_cloud_free(c);
    ok(frep_cloud_new(1, x, y, z, nx, NULL, nz, collect, &s) == NULL && s.errors == 1,
       "normals must come as three arrays (error reported)");

    write_text(tmp("bad.xyz"), "0 0 0\n1 2 3 4 5\n");
    memset(&s, 0, sizeof s);
    ok(frep_cloud_read(tmp("bad.xyz"), collect, &s) == NULL && s.errors == 1 &&
           strstr(s.last, "bad.xyz:2:") != NULL, "a bad line: '%s'", s.last);
    memset(&s, 0, sizeof s);
    ok(frep_cloud_read(tmp("none.xyz"), collect, &s) == NULL && s.errors == 1,
       "a missing file: '%s'", s.last);
    ok(frep_cloud_read(tmp("none.xyz"), NULL, NULL) == NULL, "no callback: quiet failure");
}

static void test_mesh(void)
{
    seen s = { 0 };
    frep_program *p = compile("m(x[3], a[1]) { m = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }", &s);
    if (!p) return;
    frep_mesh_options o;
    frep_mesh_options_init(&o);
    ok(o.grid == 64 && !o.has_box && o.iso == 0 && !o.params, "mesh defaults: grid 64, model box");
    o.has_box = 1;
    for (int i = 0; i < 3; i++) o.box[i] = -1.5, o.box[i + 3] = 1.5;
    o.grid = 24;
    frep_mesh_info info;
    frep_mesh *m = frep_polygonize(p, &o, &info, collect, &s);
    ok(m && frep_mesh_ntris(m) > 100 && frep_mesh_normals(m) && info.grid == 24 &&
           !info.touches_box && !info.full, "the unit sphere: %zu triangles",
       m ? frep_mesh_ntris(m) : 0);
    frep_mesh_check_result r;
    ok(m && frep_mesh_check(m, 1, &r, collect, &s) == 0 && r.open_edges == 0 &&
           r.nonmanifold_edges == 0 && r.flipped_edges == 0 && r.nonmanifold_verts == 0 &&
           r.degenerate == 0 && r.self_intersections == 0, "closed, manifold, oriented");
    is_double(m ? r.volume : 0, 4.18879, 0.05, "volume near 4/3 pi");
    /* a copy through frep_mesh_new has the same arrays */
    if (m) {
        size_t nv = frep_mesh_nverts(m), nt = frep_mesh_ntris(m);
        frep_mesh *c = frep_mesh_new(nv, frep_mesh_vertices(m), frep_mesh_normals(m), nt,
                                     frep_mesh_triangles(m), collect, &s);
        ok(c && frep_mesh_nverts(c) == nv && frep_mesh_ntris(c) == nt &&
               memcmp(frep_mesh_vertices(c), frep_mesh_vertices(m), 3 * nv * sizeof(double)) == 0 &&
               memcmp(frep_mesh_triangles(c), frep_mesh_triangles(m), 3 * nt * 4) == 0,
           "frep_mesh_new copies");
        frep_mesh_free(c);
    }
    uint32_t badtri[3] = { 0, 1, 3 };
    double v[9] = { 0, 0, 0, 1, 0, 0, 0, 1, 0 };
    memset(&s, 0, sizeof s);
    ok(frep_mesh_new(3, v, NULL, 1, badtri, collect, &s) == NULL && s.errors == 1,
       "a triangle naming vertex 3 of 3 is refused: '%s'", s.last);
    memset(&s, 0, sizeof s);
    ok(m && frep_mesh_write(m, tmp("m.xyz"), FREP_MESH_AUTO, 0, collect, &s) == -1 &&
           s.errors == 1, "an unknown mesh extension: '%s'", s.last);
    frep_mesh_free(m);

    /* runtime errors of the model come back as one warning with the source position */
    frep_program *q = compile("m(x[3], a[1]) {\n  m = sqrt(x[1]) - 0.5;\n}\n", &s);
    memset(&s, 0, sizeof s);
    o.grid = 8;
    m = q ? frep_polygonize(q, &o, &info, collect, &s) : NULL;
    ok(m && s.warnings == 2 && s.errors == 0 && s.positioned == 1 && strstr(s.last, "NaN"),
       "sqrt of negatives: a warning at the sqrt's line, one of the NaN count ('%s')", s.last);
    frep_mesh_free(m);
    frep_program_free(q);
    memset(&s, 0, sizeof s);
    o.grid = FREP_MESH_MAX_GRID + 1;
    ok(frep_polygonize(p, &o, NULL, collect, &s) == NULL && s.errors == 1,
       "grid above the limit: '%s'", s.last);
    frep_program_free(p);
}

/* The model's colours at the vertices (frep_mesh_colors): tests/models/color_sphere.hf's
 * formulas, red (x+1)/2, green y^2, blue 1.5 z clamped to [0, 1], at each vertex (the
 * vertices are within a fraction of a cell of the surface, where the colours change by
 * a few 1/255 at most); a model without colours gives none. */
static void test_mesh_colors(void)
{
    seen s = { 0 };
    frep_program *p = compile("m(x[3], a[1], s[3]) {\n  f = 0.64 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3];\n"
                              "  d = hfA_SetColor(f, s, (x[1] + 1) / 2, x[2]*x[2], 1.5*x[3]);\n  m = f;\n}\n", &s);
    frep_program *q = compile("m(x[3], a[1]) { m = 1 - x[1]*x[1] - x[2]*x[2] - x[3]*x[3]; }", &s);
    if (!p || !q) return;
    frep_mesh_options o;
    frep_mesh_options_init(&o);
    o.has_box = 1;
    for (int i = 0; i < 3; i++) o.box[i] = -1, o.box[i + 3] = 1;
    o.grid = 32;
    frep_mesh *m = frep_polygonize(p, &o, NULL, collect, &s);
    uint8_t *rgb = (uint8_t *)1;
    frep_runtime_error re;
    int worst = 0;
    ok(m && frep_mesh_colors(p, m, 2.0 / 32, 0, NULL, 2, &rgb, &re) == 0 && rgb && re.count == 0,
       "frep_mesh_colors: colours for a model with s[1..3]");
    for (size_t i = 0; m && rgb && i < frep_mesh_nverts(m); i++) {
        const double *v = frep_mesh_vertices(m) + 3 * i;
        double want[3] = { (v[0] + 1) / 2, v[1] * v[1], 1.5 * v[2] };
        for (int k = 0; k < 3; k++) {
            double w = want[k] < 0 ? 0 : want[k] > 1 ? 255 : want[k] * 255;
            int d = abs((int)rgb[3 * i + k] - (int)lround(w));
            worst = d > worst ? d : worst;
        }
    }
    ok(m && rgb && worst <= 4, "... the model's formulas at the vertices (largest difference %d/255)",
       worst);
    frep_free(rgb);
    frep_mesh_free(m);
    m = frep_polygonize(q, &o, NULL, collect, &s);
    rgb = (uint8_t *)1;
    ok(m && frep_mesh_colors(q, m, 2.0 / 32, 0, NULL, 1, &rgb, NULL) == 0 && rgb == NULL,
       "a model without colours: none, and no error");
    frep_mesh_free(m);
    frep_program_free(p);
    frep_program_free(q);
}

/* Run the frep command; 0 when it exits 0. */
static int run(const char *cmd)
{
    char line[4096];
    snprintf(line, sizeof line, "%s >/dev/null 2>&1", cmd);
    return system(line);
}

/* The command's files and the API's for the same options: byte for byte. */
static void test_same_as_command(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/examples/csg.hf", srcdir);
    seen s = { 0 };
    size_t len = 0;
    char *text = NULL;
    FILE *f = fopen(model, "rb");
    if (f) {
        text = malloc(1 << 16);
        len = text ? fread(text, 1, 1 << 16, f) : 0;
        fclose(f);
    }
    frep_program *p = text ? frep_compile(model, text, len, NULL, collect, &s) : NULL;
    free(text);
    ok(p != NULL, "examples/csg.hf compiles");
    if (!p) return;

    frep_mesh_options o;
    frep_mesh_options_init(&o);
    o.grid = 40;
    frep_mesh *m = frep_polygonize(p, &o, NULL, collect, &s);
    static const char *ext[] = { "stl", "obj", "ply", "off" };
    for (int k = 0; k < 4; k++) {
        for (int ascii = 0; ascii < 2; ascii++) {
            if (ascii && (k == 1 || k == 3)) continue;   /* OBJ and OFF are text anyway */
            char a[64], b[64];
            snprintf(a, sizeof a, "cli%d.%s", ascii, ext[k]);
            snprintf(b, sizeof b, "api%d.%s", ascii, ext[k]);
            snprintf(cmd, sizeof cmd, "'%s' mesh '%s' -g 40 %s -o '%s'", frep, model,
                     ascii ? "--ascii" : "", tmp(a));
            int rc = run(cmd);
            int w = m ? frep_mesh_write(m, tmp(b), FREP_MESH_AUTO, ascii, collect, &s) : -1;
            ok(rc == 0 && w == 0 && same_file(tmp(a), tmp(b)),
               "frep mesh -g 40%s -o .%s: the same bytes", ascii ? " --ascii" : "", ext[k]);
        }
    }

    frep_sample_options so;
    frep_sample_options_init(&so);
    so.n = 2000;
    so.seed = 42;
    so.noise = 0.002;
    so.outliers = 0.05;
    frep_cloud *c = frep_sample(p, &so, collect, &s);
    for (int k = 0; k < 2; k++) {
        const char *e = k ? "ply" : "xyz";
        char a[64], b[64];
        snprintf(a, sizeof a, "cli.%s", e);
        snprintf(b, sizeof b, "api.%s", e);
        snprintf(cmd, sizeof cmd,
                 "'%s' sample '%s' -n 2000 --seed 42 --noise 0.002 --outliers 0.05 -o '%s'",
                 frep, model, tmp(a));
        int rc = run(cmd);
        int w = c ? frep_cloud_write(c, tmp(b), collect, &s) : -1;
        ok(rc == 0 && w == 0 && same_file(tmp(a), tmp(b)),
           "frep sample -n 2000 --seed 42 --noise --outliers -o .%s: the same bytes", e);
    }
    frep_cloud_free(c);

    /* NULL options: the defaults (10000 points, seed 1), as frep sample with them */
    c = frep_sample(p, NULL, collect, &s);
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 10000 --seed 1 -o '%s'", frep, model,
             tmp("clid.xyz"));
    ok(run(cmd) == 0 && c && frep_cloud_write(c, tmp("apid.xyz"), collect, &s) == 0 &&
           same_file(tmp("clid.xyz"), tmp("apid.xyz")),
       "frep_sample with NULL options: the defaults of frep sample");
    frep_cloud_free(c);

    /* sampling a mesh file */
    frep_mesh *mr = frep_mesh_read(tmp("cli0.off"), collect, &s);
    ok(mr && m && frep_mesh_ntris(mr) == frep_mesh_ntris(m), "the .off file read back");
    so.noise = 0;
    so.outliers = 0;
    so.n = 500;
    so.seed = 9;
    c = mr ? frep_sample_mesh(mr, &so, collect, &s) : NULL;
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 500 --seed 9 -o '%s'", frep, tmp("cli0.off"),
             tmp("clim.xyz"));
    int rc = run(cmd);
    ok(rc == 0 && c && frep_cloud_write(c, tmp("apim.xyz"), collect, &s) == 0 &&
           same_file(tmp("clim.xyz"), tmp("apim.xyz")), "frep sample MESH.off: the same bytes");
    frep_cloud_free(c);
    frep_mesh_free(mr);
    frep_mesh_free(m);
    frep_program_free(p);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");
}


/* progress and cancel of frep_segment: how often each was called */
typedef struct seg_calls {
    int progress, cancel, stop_at;
} seg_calls;

static void seg_progress(void *user, const char *stage, size_t done, size_t total, size_t nprims)
{
    (void)stage, (void)done, (void)total, (void)nprims;
    ((seg_calls *)user)->progress++;
}

static int seg_cancel(void *user)
{
    seg_calls *c = user;
    return ++c->cancel >= c->stop_at;
}

/* frep segment and frep_segment on the same cloud and seed: the same .fit bytes and
 * labels; a cancel stops detection early with what was found. */
static void test_segment(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/tests/models/segment_box.hf", srcdir);
    seen s = { 0 };
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 6000 --seed 5 --noise 0.002 -q -o '%s'", frep,
             model, tmp("box.xyz"));
    ok(run(cmd) == 0, "a box cloud from frep sample");
    snprintf(cmd, sizeof cmd, "'%s' segment '%s' --seed 3 -q -o '%s' --labels '%s'", frep,
             tmp("box.xyz"), tmp("cli.fit"), tmp("cli.labels"));
    ok(run(cmd) == 0, "frep segment --seed 3");
    frep_cloud *c = frep_cloud_read(tmp("box.xyz"), collect, &s);
    frep_segment_options o;
    frep_segment_options_init(&o);
    ok(o.seed == 1 && o.separating == 1 && o.types == 0 && !o.cancel, "segment defaults");
    o.seed = 3;
    seg_calls calls = { 0, 0, 1 << 30 };
    o.progress = seg_progress;
    o.cancel = seg_cancel;
    o.user = &calls;
    frep_segmentation *g = c ? frep_segment(c, &o, collect, &s) : NULL;
    ok(g && frep_segmentation_nfitted(g) >= 6 && !frep_segmentation_interrupted(g) &&
           calls.progress > 0 && calls.cancel == calls.progress,
       "frep_segment: %zu fitted, %zu in all; progress called %d times, cancel polled as often",
       g ? frep_segmentation_nfitted(g) : 0, g ? frep_segmentation_nprims(g) : 0, calls.progress);
    ok(g && frep_segmentation_write(g, tmp("api.fit"), NULL, collect, &s) == 0 &&
           same_file(tmp("cli.fit"), tmp("api.fit")), "the same .fit bytes as frep segment");
    /* the labels file holds label + 1 per point */
    FILE *lf = fopen(tmp("cli.labels"), "r");
    int same = lf && g;
    const int32_t *lab = g ? frep_segmentation_labels(g) : NULL;
    for (size_t i = 0; same && i < frep_cloud_size(c); i++) {
        long v;
        same = fscanf(lf, "%ld", &v) == 1 && v == (long)lab[i] + 1;
    }
    if (lf) fclose(lf);
    ok(same, "the same labels as frep segment --labels");
    int w = g ? frep_segmentation_write(g, tmp("api.hf"), "segmented by test_api", collect, &s) : -1;
    char text[1 << 16];
    FILE *hf = fopen(tmp("api.hf"), "rb");
    size_t len = hf ? fread(text, 1, sizeof text, hf) : 0;
    if (hf) fclose(hf);
    frep_program *hp = frep_compile("api.hf", text, len, NULL, collect, &s);
    ok(w == 0 && hp && memmem(text, len, "-- segmented by test_api", 24),
       "written as a .hf model that compiles, with its header");
    frep_program_free(hp);
    frep_segmentation_free(g);

    /* stop at the third poll: interrupted, fewer primitives */
    calls = (seg_calls){ 0, 0, 3 };
    g = c ? frep_segment(c, &o, collect, &s) : NULL;
    ok(g && frep_segmentation_interrupted(g) && calls.cancel == 3 &&
           frep_segmentation_nfitted(g) < 6, "cancel after 3 polls: interrupted with %zu primitives",
       g ? frep_segmentation_nfitted(g) : 0);
    frep_segmentation_free(g);
    frep_cloud_free(c);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");
}

/* A copy of c without its normals (the points of a scan). */
static frep_cloud *bare_copy(const frep_cloud *c, seen *s)
{
    const double *x, *y, *z;
    frep_cloud_arrays(c, &x, &y, &z, NULL, NULL, NULL);
    return frep_cloud_new(frep_cloud_size(c), x, y, z, NULL, NULL, NULL, collect, s);
}

static char *slurp(const char *path, size_t *len);

/* Normals of the cloud (n points) that point into the solid of the model in `path`: a
 * step of h along the normal raises f (the solid is f >= 0). This and not the sign
 * against the sampler's normal is what "inward" means at an edge, where a normal of
 * either face is right: on the box's perpendicular faces the two are at 90 degrees, and
 * the dot with the other face's normal is noise around 0. SIZE_MAX when the model
 * cannot be evaluated. */
static size_t count_inward(const char *path, const frep_cloud *c, double h)
{
    size_t len, inward = 0, n = frep_cloud_size(c);
    char *text = slurp(path, &len);
    frep_program *p = text ? frep_compile(path, text, len, NULL, NULL, NULL) : NULL;
    frep_scratch *sc = p ? frep_scratch_new(p) : NULL;
    const double *x, *y, *z, *nx, *ny, *nz;
    frep_cloud_arrays(c, &x, &y, &z, &nx, &ny, &nz);
    for (size_t i = 0; sc && i < n; i++) {
        double px[2] = { x[i] + h * nx[i], x[i] - h * nx[i] };
        double py[2] = { y[i] + h * ny[i], y[i] - h * ny[i] };
        double pz[2] = { z[i] + h * nz[i], z[i] - h * nz[i] };
        double f[2];
        if (frep_eval(p, sc, 2, px, py, pz, NULL, f) != 0) {
            inward = SIZE_MAX;
            break;
        }
        inward += f[0] > f[1];
    }
    if (sc == NULL) inward = SIZE_MAX;
    frep_scratch_free(sc);
    frep_program_free(p);
    free(text);
    return inward;
}

/* frep normals and frep_normals on the same bare cloud: the same files, automatic and
 * fixed neighbourhoods; the checks and the knn range refused with a message; a raised
 * cancel flag stops the estimate. */
static void test_normals(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/tests/models/segment_box.hf", srcdir);
    seen s = { 0 };
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 4000 --seed 7 --noise 0.001 -q -o '%s'", frep,
             model, tmp("nb.xyz"));
    ok(run(cmd) == 0, "a box cloud from frep sample");
    frep_cloud *full = frep_cloud_read(tmp("nb.xyz"), collect, &s);
    frep_cloud *bare = full ? bare_copy(full, &s) : NULL;
    ok(bare && !frep_cloud_has_normals(bare) &&
           frep_cloud_write(bare, tmp("bare.xyz"), collect, &s) == 0,
       "written without normals (3 columns)");
    frep_normals_options o;
    frep_normals_options_init(&o);
    ok(o.knn == 0 && o.nthreads == 0 && !o.cancel_flag, "normals defaults: knn from the data");
    static const size_t knns[] = { 0, 20 };
    static const char *outs[] = { "n.xyz", "n.ply" };
    for (int t = 0; t < 2; t++) {
        char cli[64], api[64], knn[32] = "";
        snprintf(cli, sizeof cli, "cli_%s", outs[t]);
        snprintf(api, sizeof api, "api_%s", outs[t]);
        if (knns[t]) snprintf(knn, sizeof knn, " --knn %zu", knns[t]);
        snprintf(cmd, sizeof cmd, "'%s' normals '%s' -q -t 1%s -o '%s'", frep, tmp("bare.xyz"),
                 knn, tmp(cli));
        ok(run(cmd) == 0, "frep normals%s -o %s", knn, outs[t]);
        frep_cloud *c = frep_cloud_read(tmp("bare.xyz"), collect, &s);
        o.knn = knns[t];
        o.nthreads = 2;
        frep_normals_info info;
        int rc = c ? frep_normals(c, &o, &info, collect, &s) : -1;
        ok(rc == 0 && frep_cloud_has_normals(c) && info.knn >= FREP_NORMALS_MIN_KNN &&
               (knns[t] == 0 || info.knn == knns[t]) && info.spacing > 0 &&
               info.components >= 1 && !info.interrupted,
           "frep_normals: %zu neighbours, spacing %g, noise %g, %zu part(s)", info.knn,
           info.spacing, info.noise, info.components);
        ok(c && frep_cloud_write(c, tmp(api), collect, &s) == 0 && same_file(tmp(cli), tmp(api)),
           "the same %s bytes as frep normals%s (2 threads against 1)", outs[t], knn);
        /* all outward (the model tells); against the sampler's exact normals within
         * 60 degrees but at the box's edges, where a neighbourhood spans two faces */
        const double *nx, *ny, *nz, *fx, *fy, *fz;
        size_t n = c ? frep_cloud_size(c) : 0, close = 0;
        size_t inward = c ? count_inward(model, c, 0.02) : SIZE_MAX;
        if (c) {
            frep_cloud_arrays(c, NULL, NULL, NULL, &nx, &ny, &nz);
            frep_cloud_arrays(full, NULL, NULL, NULL, &fx, &fy, &fz);
            for (size_t i = 0; i < n; i++)
                close += nx[i] * fx[i] + ny[i] * fy[i] + nz[i] * fz[i] > 0.5;
        }
        ok(n == 4000 && inward == 0 && close > 0.97 * (double)n,
           "%zu of %zu normals within 60 degrees of the surface's, %zu inward", close, n, inward);
        frep_cloud_free(c);
    }
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");

    /* refused: knn out of range, a cloud of too few points, points on one line */
    seen e = { 0 };
    o.knn = FREP_NORMALS_MIN_KNN - 1;
    ok(frep_normals(bare, &o, NULL, collect, &e) == -1 && e.errors == 1 &&
           strstr(e.last, "knn 2") != NULL, "knn 2 refused (%s)", e.last);
    o.knn = FREP_NORMALS_MAX_KNN + 1;
    ok(frep_normals(bare, &o, NULL, collect, &e) == -1 && e.errors == 2, "knn %d refused",
       FREP_NORMALS_MAX_KNN + 1);
    o.knn = FREP_NORMALS_MAX_KNN;
    ok(frep_normals(bare, &o, NULL, collect, &e) == 0 && e.errors == 2,
       "knn %d, the largest, taken", FREP_NORMALS_MAX_KNN);
    double lx[4] = { 0, 1, 2, 3 }, ly[4] = { 0, 1, 2, 3 }, lz[4] = { 0, 0, 0, 0 };
    double pz[4] = { 0, 0, 0, 0 }, py[4] = { 0, 1, 0, 1 };
    frep_cloud *two = frep_cloud_new(2, lx, ly, lz, NULL, NULL, NULL, collect, &e);
    ok(two && frep_normals(two, NULL, NULL, collect, &e) == -1 &&
           strcmp(e.last, "the cloud: too few points: 2 (at least 3 needed)") == 0,
       "2 points refused (%s)", e.last);
    frep_cloud *line = frep_cloud_new(4, lx, ly, lz, NULL, NULL, NULL, collect, &e);
    int planar = -1;
    ok(line && frep_cloud_check(line, "line.xyz", &planar, collect, &e) == -1 &&
           strcmp(e.last, "line.xyz: all 4 points lie on one line") == 0 && planar == 0,
       "frep_cloud_check: %s", e.last);
    frep_cloud *flat = frep_cloud_new(4, lx, py, pz, NULL, NULL, NULL, collect, &e);
    int errs = e.errors;
    ok(flat && frep_cloud_check(flat, NULL, &planar, collect, &e) == 0 && planar == 1 &&
           e.errors == errs, "frep_cloud_check: 4 points on a plane pass, planar");
    ok(frep_cloud_check(bare, NULL, &planar, collect, &e) == 0 && planar == 0,
       "frep_cloud_check: the box's points are not planar");
    frep_cloud_free(two);
    frep_cloud_free(line);
    frep_cloud_free(flat);

    /* a flag raised before the call: stopped, no message */
    volatile sig_atomic_t stop = 1;
    frep_normals_options_init(&o);
    o.cancel_flag = &stop;
    frep_normals_info info;
    errs = e.errors;
    ok(frep_normals(bare, &o, &info, collect, &e) == 1 && info.interrupted && e.errors == errs,
       "a raised cancel flag stops the estimate (returns 1)");
    frep_cloud_free(bare);
    frep_cloud_free(full);
}

/* frep segment on a cloud without normals estimates them as frep normals, and so does
 * frep_segment; the figures and primitives the summary prints come through the API. */
static void test_segment_bare(const char *frep)
{
    char cmd[2048];
    seen s = { 0 };
    snprintf(cmd, sizeof cmd, "'%s' segment '%s' --seed 4 -q -o '%s' --labels '%s'", frep,
             tmp("bare.xyz"), tmp("bare_cli.fit"), tmp("bare_cli.labels"));
    ok(run(cmd) == 0, "frep segment on a cloud without normals");
    frep_cloud *c = frep_cloud_read(tmp("bare.xyz"), collect, &s);
    frep_segment_options o;
    frep_segment_options_init(&o);
    ok(!o.cancel_flag, "no cancel flag by default");
    o.seed = 4;
    frep_segmentation *g = c ? frep_segment(c, &o, collect, &s) : NULL;
    ok(g && frep_cloud_has_normals(c) &&
           frep_segmentation_write(g, tmp("bare_api.fit"), NULL, collect, &s) == 0 &&
           same_file(tmp("bare_cli.fit"), tmp("bare_api.fit")),
       "frep_segment: the same .fit bytes as frep segment, normals estimated into the cloud");
    frep_segment_info info;
    if (g) frep_segmentation_get_info(g, &info);
    ok(g && info.npoints == 4000 && info.nprims == frep_segmentation_nprims(g) &&
           info.nfitted == frep_segmentation_nfitted(g) && info.normals_estimated &&
           info.unassigned == frep_segmentation_unassigned(g) && info.epsilon > 0 &&
           info.diagonal > 0 && !info.interrupted,
       "frep_segmentation_get_info: %zu points, %zu primitives, epsilon %g", g ? info.npoints : 0,
       g ? info.nprims : 0, g ? info.epsilon : 0.0);
    /* primitives: the box's planes first (unit normals), then separating ones */
    size_t nfit = 0, bad = 0, nsep = 0;
    for (size_t j = 0; g && j < info.nprims; j++) {
        frep_prim q;
        if (frep_segmentation_get_prim(g, j, &q) != 0) bad++;
        if (q.separating) nsep++;
        else if (nsep) bad++;   /* a fitted one after a separating one */
        else {
            nfit++;
            double len = sqrt(q.p[0] * q.p[0] + q.p[1] * q.p[1] + q.p[2] * q.p[2]);
            bad += q.type != FREP_PRIM_PLANE || fabs(len - 1) > 1e-9 || q.support == 0;
        }
    }
    frep_prim q;
    ok(g && bad == 0 && nfit == info.nfitted && nfit >= 6 &&
           frep_segmentation_get_prim(g, info.nprims, &q) == -1,
       "frep_segmentation_get_prim: %zu fitted planes (unit normals) before %zu separating",
       nfit, nsep);
    frep_segmentation_free(g);
    frep_cloud_free(c);

    /* a fixed neighbourhood: the segmenter's own estimate, as the command's */
    snprintf(cmd, sizeof cmd, "'%s' segment '%s' --seed 4 --knn 20 -q -o '%s'", frep,
             tmp("bare.xyz"), tmp("bare_cli20.fit"));
    ok(run(cmd) == 0, "frep segment --knn 20 on a cloud without normals");
    c = frep_cloud_read(tmp("bare.xyz"), collect, &s);
    o.knn = 20;
    g = c ? frep_segment(c, &o, collect, &s) : NULL;
    ok(g && frep_segmentation_write(g, tmp("bare_api20.fit"), NULL, collect, &s) == 0 &&
           same_file(tmp("bare_cli20.fit"), tmp("bare_api20.fit")),
       "frep_segment with knn 20: the same .fit bytes as frep segment --knn 20");
    frep_segmentation_free(g);
    frep_cloud_free(c);

    is_str(frep_prim_type_name(FREP_PRIM_CYLINDER), "cylinder", "frep_prim_type_name");
    ok(frep_prim_type_name(FREP_PRIM_NTYPES) == NULL && frep_prim_type_name(-1) == NULL,
       "frep_prim_type_name: NULL out of range");
    char buf[FREP_NUMBER_BUF], small[4];
    is_str(frep_format_number(buf, sizeof buf, 0.12345678, 1e-3), "0.123",
           "frep_format_number: within half a quantum");
    is_str(frep_format_number(buf, sizeof buf, 1e-9, 1e-6), "0", "frep_format_number: 0 below");
    is_str(frep_format_number(buf, sizeof buf, 0.1, 0), "0.1", "frep_format_number: exact");
    is_str(frep_format_number(small, sizeof small, 123.456, 0), "123",
           "frep_format_number: truncated to the buffer");
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");
}

/* progress and cancel of frep_fit_template: how often each was called */
typedef struct fit_calls {
    int progress, cancel, stop_at;
} fit_calls;

static void fit_progress(void *user, const frep_fit_progress *p)
{
    (void)p;
    ((fit_calls *)user)->progress++;
}

static int fit_cancel(void *user)
{
    fit_calls *c = user;
    return ++c->cancel >= c->stop_at;
}

/* Read a whole (small) file; NULL when it cannot. */
static char *slurp(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    char *t = malloc(1 << 16);
    *len = t ? fread(t, 1, (1 << 16) - 1, f) : 0;
    if (t) t[*len] = '\0';
    fclose(f);
    return t;
}

/* frep fit and frep_fit_template on the same template, cloud and seed: the same fitted
 * template bytes, the same JSON report but for its "seconds"; the truth recovered;
 * the a[] form; a cancel keeps the best so far; bad input reported. */
static void test_fit(const char *frep)
{
    static const char tmpl[] =
        "-- a sphere of unknown centre and radius\n"
        "my_model(x[3], a[1]) {\n"
        "  cx = 0;     -- @free [-1, 1]\n"
        "  r = 1;      -- @free [0.2, 3]\n"
        "  my_model = r*r - (x[1]-cx)*(x[1]-cx) - x[2]*x[2] - x[3]*x[3];\n}\n";
    static const char truth[] =
        "my_model(x[3], a[1]) {\n"
        "  my_model = 1.44 - (x[1]-0.3)*(x[1]-0.3) - x[2]*x[2] - x[3]*x[3];\n}\n"
        "-- @box -2 -2 -2 2 2 2\n";
    write_text(tmp("sphere.hf"), tmpl);
    write_text(tmp("truth.hf"), truth);
    seen s = { 0 };
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 1500 --seed 4 --noise 0.001 -q -o '%s'",
             frep, tmp("truth.hf"), tmp("sphere.xyz"));
    ok(run(cmd) == 0, "a sphere cloud from frep sample");
    snprintf(cmd, sizeof cmd, "'%s' fit '%s' '%s' --seed 7 -q -o '%s' --json '%s'", frep,
             tmp("sphere.hf"), tmp("sphere.xyz"), tmp("cli.fitted.hf"), tmp("cli.json"));
    ok(run(cmd) == 0, "frep fit --seed 7");

    frep_fit_options o;
    frep_fit_options_init(&o);
    ok(o.seed == 1 && o.method == FREP_FIT_SAQN && o.robust == 1 && o.sa_chains == 2 &&
           o.sa_points == 1024 && !o.cancel && !o.progress, "fit defaults");
    o.seed = 7;
    fit_calls calls = { 0, 0, 1 << 30 };
    o.progress = fit_progress;
    o.cancel = fit_cancel;
    o.user = &calls;
    frep_cloud *c = frep_cloud_read(tmp("sphere.xyz"), collect, &s);
    frep_fit *f = c ? frep_fit_template(tmp("sphere.hf"), tmpl, strlen(tmpl), NULL, c, &o,
                                        collect, &s) : NULL;
    ok(f != NULL, "frep_fit_template runs");
    if (f) {
        frep_fit_info in;
        frep_fit_get_info(f, &in);
        frep_fit_param pc, pr;
        ok(frep_fit_nparams(f) == 2 && frep_fit_get_param(f, 0, &pc) == 0 &&
               frep_fit_get_param(f, 1, &pr) == 0 && frep_fit_get_param(f, 2, &pr) == -1 &&
               frep_fit_get_param(f, 1, &pr) == 0,
           "two fitted parameters, the third out of range");
        ok(strcmp(pc.name, "cx") == 0 && strcmp(pr.name, "r") == 0 && pr.index == 2 &&
               pc.start == 0 && pr.start == 1 && pr.lo == 0.2 && pr.hi == 3,
           "named with their start and bounds (r at index 2 after a[1] and cx)");
        ok(fabs(pc.value - 0.3) < 0.005 && fabs(pr.value - 1.2) < 0.005,
           "the truth recovered: cx %.5f (0.3), r %.5f (1.2)", pc.value, pr.value);
        /* the noise: 0.001 of the box's diagonal 4 sqrt(3), 0.0069 */
        ok(in.npoints == 1500 && in.nparams == 2 && in.converged && !in.interrupted &&
               strncmp(in.verdict, "good", 4) == 0 && in.rms > 0.5 * 0.0069 &&
               in.rms < 1.5 * 0.0069,
           "info: converged, rms %g, verdict '%s'", in.rms, in.verdict);
        ok(calls.progress > 0 && calls.cancel >= calls.progress,
           "progress called %d times, cancel polled at least as often (%d)", calls.progress,
           calls.cancel);
        double v[3] = { 9, 9, 9 };
        ok(frep_fit_nvalues(f) == 3 && frep_fit_values(f, v, 2) == -1 && v[0] == 9 &&
               frep_fit_values(f, v, 3) == 0 && v[1] == pc.value && v[2] == pr.value,
           "the whole parameter vector with the fitted values");
        ok(frep_fit_write(f, tmp("api.fitted.hf"), collect, &s) == 0 &&
               same_file(tmp("cli.fitted.hf"), tmp("api.fitted.hf")),
           "the same fitted template bytes as frep fit");
        size_t tl = 0;
        const char *t = frep_fit_text(f, &tl);
        ok(t && tl == strlen(t) && strstr(t, "-- @box ") && strstr(t, "-- @free [0.2, 3]"),
           "frep_fit_text: the fitted template, annotations kept, a @box line");
        ok(frep_fit_write_json(f, tmp("api.json"), tmp("sphere.hf"), tmp("sphere.xyz"),
                               tmp("cli.fitted.hf"), collect, &s) == 0, "JSON report written");
        /* the same report but for the wall time */
        size_t la = 0, lb = 0;
        char *ja = slurp(tmp("cli.json"), &la), *jb = slurp(tmp("api.json"), &lb);
        int same = ja && jb;
        for (char *x = ja, *y = jb; same && x && y;) {
            char *ex = strchr(x, '\n'), *ey = strchr(y, '\n');
            size_t nx = ex ? (size_t)(ex - x) : strlen(x), ny = ey ? (size_t)(ey - y) : strlen(y);
            if (!strstr(x, "\"seconds\"") || (ex && strstr(x, "\"seconds\"") > ex))
                same = nx == ny && memcmp(x, y, nx) == 0;
            x = ex ? ex + 1 : NULL;
            y = ey ? ey + 1 : NULL;
            if (!x != !y) same = 0;
        }
        ok(same && la > 100, "the same JSON report as frep fit --json (but \"seconds\")");
        free(ja);
        free(jb);
    }
    frep_fit_free(f);

    /* a cancel at the first poll: interrupted, the best so far kept */
    calls = (fit_calls){ 0, 0, 1 };
    f = c ? frep_fit_template(tmp("sphere.hf"), tmpl, strlen(tmpl), NULL, c, &o, collect, &s)
          : NULL;
    frep_fit_info in = { 0 };
    if (f) frep_fit_get_info(f, &in);
    ok(f && in.interrupted && calls.cancel >= 1 && strcmp(in.status, "interrupted") == 0 &&
           strstr(in.verdict, "stopped before the end"),
       "cancelled: interrupted, a result (%s)", f ? in.verdict : "none");
    frep_fit_free(f);

    /* the a[] form, started from copt.a, with bounds */
    static const char atmpl[] =
        "my_model(x[3], a[2]) {\n"
        "  my_model = a[2]*a[2] - (x[1]-a[1])*(x[1]-a[1]) - x[2]*x[2] - x[3]*x[3];\n}\n";
    frep_compile_options co;
    frep_compile_options_init(&co);
    double a0[2] = { 0, 1 }, lo[2] = { -1, 0.2 }, hi[2] = { 1, 3 };
    co.a = a0;
    co.na = 2;
    frep_fit_options_init(&o);
    o.method = FREP_FIT_QN;
    o.lo = lo;
    o.hi = hi;
    o.nbounds = 2;
    f = c ? frep_fit_template("a.hf", atmpl, strlen(atmpl), &co, c, &o, collect, &s) : NULL;
    double v[2] = { 0, 0 };
    ok(f && frep_fit_values(f, v, 2) == 0 && fabs(v[0] - 0.3) < 0.005 &&
           fabs(v[1] - 1.2) < 0.005 && strstr(frep_fit_text(f, NULL), "-- @params "),
       "a[] template by quasi-Newton: a = %.5f, %.5f and a '-- @params' line", v[0], v[1]);
    frep_fit_free(f);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");

    /* errors through the callback, NULL back */
    static const char none[] = "my_model(x[3], a[1]) {\n  my_model = 1 - x[1]*x[1];\n}\n";
    seen e = { 0 };
    f = c ? frep_fit_template("none.hf", none, strlen(none), NULL, c, NULL, collect, &e) : NULL;
    ok(!f && e.errors == 1 && strstr(e.last, "no free parameters"),
       "no free parameters: an error (%s)", e.last);
    e = (seen){ 0 };
    f = frep_fit_template("bad.hf", "my_model(x[3] {", 15, NULL, c, NULL, collect, &e);
    ok(!f && e.errors >= 1 && e.positioned >= 1, "a syntax error with its position (%s)", e.last);
    double px[5] = { 0, 1, 0, 0, 1 }, py[5] = { 0, 0, 1, 0, 1 }, pz[5] = { 0, 0, 0, 1, 1 };
    frep_cloud *small = frep_cloud_new(5, px, py, pz, NULL, NULL, NULL, collect, &e);
    e = (seen){ 0 };
    f = small ? frep_fit_template("s.hf", tmpl, strlen(tmpl), NULL, small, NULL, collect, &e)
              : NULL;
    ok(!f && e.errors == 1 && strstr(e.last, "too few"), "5 points: too few (%s)", e.last);
    frep_cloud_free(small);
    frep_cloud_free(c);
}

/* frep render and frep_render on the same mesh and cloud: the same PNG bytes, with
 * and without points, for a model and for a mesh file; bad options reported. */
/* The model file at path compiled and polygonized at grid (*m NULL when either fails). */
static frep_program *compile_and_mesh(const char *path, int grid, seen *s, frep_mesh **m)
{
    size_t len = 0;
    char *text = slurp(path, &len);
    frep_program *p = text ? frep_compile(path, text, len, NULL, collect, s) : NULL;
    free(text);
    frep_mesh_options mo;
    frep_mesh_options_init(&mo);
    mo.grid = grid;
    *m = p ? frep_polygonize(p, &mo, NULL, collect, s) : NULL;
    return p;
}

static void test_render(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/examples/csg.hf", srcdir);
    seen s = { 0 };
    frep_mesh *m;
    frep_program *p = compile_and_mesh(model, 32, &s, &m);
    ok(m != NULL, "examples/csg.hf polygonized at grid 32");
    if (!m) {
        frep_program_free(p);
        return;
    }
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 800 --seed 2 --noise 0.01 -q -o '%s'", frep,
             model, tmp("csg.xyz"));
    ok(run(cmd) == 0, "a cloud from frep sample");
    frep_cloud *c = frep_cloud_read(tmp("csg.xyz"), collect, &s);

    frep_render_options o;
    frep_render_options_init(&o);
    ok(o.width == 800 && o.height == 600 && strcmp(o.view, "iso") == 0 && !o.points,
       "render defaults: 800x600, iso");
    o.width = 96;
    o.height = 64;
    o.view = "top";
    snprintf(cmd, sizeof cmd, "'%s' render '%s' -g 32 --size 96x64 --view top -q -o '%s'", frep,
             model, tmp("cli0.png"));
    int rc = run(cmd);
    frep_render_info in;
    frep_image *img = frep_render(m, &o, &in, collect, &s);
    int w = 0, h = 0;
    const uint8_t *px = img ? frep_image_pixels(img, &w, &h) : NULL;
    ok(img && px && w == 96 && h == 64 && in.ntris == frep_mesh_ntris(m) && in.npoints == 0,
       "frep_render: a 96x64 picture of %zu triangles", in.ntris);
    ok(rc == 0 && img && frep_image_write_png(img, tmp("api0.png"), collect, &s) == 0 &&
           same_file(tmp("cli0.png"), tmp("api0.png")),
       "frep render -g 32 --size 96x64 --view top: the same PNG bytes");
    FILE *pf = fopen(tmp("api0s.png"), "wb");
    int wrc = pf && img ? frep_image_write_png_stream(img, pf) : -1;
    if (pf && fclose(pf) != 0) wrc = -1;
    ok(wrc == 0 && same_file(tmp("api0.png"), tmp("api0s.png")),
       "frep_image_write_png_stream: the bytes frep_image_write_png writes");
    frep_image_free(img);

    /* with the cloud, measured against the model */
    o.points = c;
    o.program = p;
    o.view = "iso";
    snprintf(cmd, sizeof cmd, "'%s' render '%s' -g 32 --size 96x64 --points '%s' -q -o '%s'",
             frep, model, tmp("csg.xyz"), tmp("cli1.png"));
    rc = run(cmd);
    img = c ? frep_render(m, &o, &in, collect, &s) : NULL;
    ok(img && in.npoints == 800 && in.mean_dist > 0 && in.max_dist > in.mean_dist &&
           in.point_scale > 0 && in.surface_scale > 0,
       "with 800 points: mean distance %.3g, max %.3g", in.mean_dist, in.max_dist);
    ok(rc == 0 && img && frep_image_write_png(img, tmp("api1.png"), collect, &s) == 0 &&
           same_file(tmp("cli1.png"), tmp("api1.png")),
       "frep render --points: the same PNG bytes");
    frep_image_free(img);

    /* a mesh file, the points measured against its triangles, --plain --scale */
    frep_mesh_write(m, tmp("csg.off"), FREP_MESH_AUTO, 0, collect, &s);
    frep_mesh *mr = frep_mesh_read(tmp("csg.off"), collect, &s);
    o.program = NULL;
    o.plain = 1;
    o.scale = 0.05;
    snprintf(cmd, sizeof cmd,
             "'%s' render '%s' --size 96x64 --points '%s' --plain --scale 0.05 -q -o '%s'", frep,
             tmp("csg.off"), tmp("csg.xyz"), tmp("cli2.png"));
    rc = run(cmd);
    img = mr && c ? frep_render(mr, &o, &in, collect, &s) : NULL;
    ok(rc == 0 && img && in.point_scale == 0.05 && in.surface_scale == 0 &&
           frep_image_write_png(img, tmp("api2.png"), collect, &s) == 0 &&
           same_file(tmp("cli2.png"), tmp("api2.png")),
       "frep render MESH.off --points --plain --scale: the same PNG bytes");
    frep_image_free(img);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");

    seen e = { 0 };
    o.view = "upside";
    ok(!frep_render(m, &o, NULL, collect, &e) && e.errors == 1 && strstr(e.last, "upside"),
       "an unknown view: an error (%s)", e.last);
    o.view = "iso";
    o.width = FREP_RENDER_MAX_SIDE + 1;
    e = (seen){ 0 };
    ok(!frep_render(m, &o, NULL, collect, &e) && e.errors == 1,
       "a side over FREP_RENDER_MAX_SIDE: an error (%s)", e.last);
    frep_mesh_free(mr);
    frep_cloud_free(c);
    frep_mesh_free(m);
    frep_program_free(p);
}

/* The a[] usage query, the fit names, the OpenSCAD export, a cloud's distances, the
 * page and the server of frep view (the public API the frep command's view, fit and
 * export run on). */
static void test_param_used(void)
{
    seen s = { 0 };
    frep_program *p = compile("m(x[3], a[3]) {\n  r = 1;  -- @free\n  q = 2;  -- @free\n"
                              "  m = r + a[2] - x[1];\n}\n", &s);
    ok(p && frep_program_nparams(p) == 5, "a[1..3], r and q: 5 parameters");
    if (!p) return;
    ok(!frep_program_param_used(p, 0) && frep_program_param_used(p, 1) &&
           !frep_program_param_used(p, 2),
       "of a[1..3] only a[2] is read");
    ok(frep_program_param_used(p, 3) && !frep_program_param_used(p, 4),
       "r is read, q is not");
    ok(!frep_program_param_used(p, 5) && !frep_program_param_used(p, (size_t)-1),
       "an index out of range is not used");
    frep_program_free(p);
}

static void test_fit_names(void)
{
    static const char *const methods[] = { "saqn", "qn", "sa", "lm" };
    static const char *const objectives[] = { "algebraic", "geometric" };
    static const char *const losses[] = { "l2", "huber", "cauchy", "geman" };
    int good = 1;
    for (int i = 0; i < 4; i++) {
        frep_fit_method m = FREP_FIT_SAQN;
        good &= frep_fit_method_parse(methods[i], &m) == 0 && (int)m == i &&
                strcmp(frep_fit_method_name(m), methods[i]) == 0;
        frep_fit_loss l = FREP_FIT_L2;
        good &= frep_fit_loss_parse(losses[i], &l) == 0 && (int)l == i &&
                strcmp(frep_fit_loss_name(l), losses[i]) == 0;
    }
    for (int i = 0; i < 2; i++) {
        frep_fit_objective k = FREP_FIT_ALGEBRAIC;
        good &= frep_fit_objective_parse(objectives[i], &k) == 0 && (int)k == i &&
                strcmp(frep_fit_objective_name(k), objectives[i]) == 0;
    }
    ok(good, "every method, objective and loss name parses to its value and back");
    frep_fit_method m = FREP_FIT_LM;
    frep_fit_objective k = FREP_FIT_GEOMETRIC;
    frep_fit_loss l = FREP_FIT_GEMAN;
    ok(frep_fit_method_parse("SAQN", &m) == -1 && frep_fit_method_parse("", &m) == -1 &&
           frep_fit_method_parse(NULL, &m) == -1 && m == FREP_FIT_LM,
       "SAQN, '' and NULL are no method; the value is untouched");
    ok(frep_fit_objective_parse("geom", &k) == -1 && k == FREP_FIT_GEOMETRIC &&
           frep_fit_loss_parse("L1", &l) == -1 && l == FREP_FIT_GEMAN,
       "geom is no objective, L1 no loss");
    ok(!frep_fit_method_name((frep_fit_method)4) && !frep_fit_objective_name((frep_fit_objective)2) &&
           !frep_fit_loss_name((frep_fit_loss)-1),
       "a value outside the enums has no name");
    frep_fit_options o;
    frep_fit_options_init(&o);
    ok(strcmp(frep_fit_method_name(o.method), "saqn") == 0 &&
           strcmp(frep_fit_loss_name(o.loss), "l2") == 0,
       "the defaults are saqn and l2");
}

static void test_export_scad(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/examples/csg.hf", srcdir);
    size_t len = 0;
    char *src = slurp(model, &len);
    frep_scad_options o;
    frep_scad_options_init(&o);
    ok(o.fn == FREP_SCAD_DEFAULT_FN && o.box[0] == -10 && o.box[5] == 10 && !o.model,
       "export defaults: $fn 48, the box [-10, 10]^3");
    frep_program *p = src ? frep_compile(model, src, len, NULL, NULL, NULL) : NULL;
    if (p) frep_program_box(p, o.box);   /* the box frep export uses */
    seen s = { 0 };
    char *text = src ? frep_export_scad(model, src, len, &o, collect, &s) : NULL;
    snprintf(cmd, sizeof cmd, "'%s' export '%s' -q -o '%s'", frep, model, tmp("cli.scad"));
    int rc = run(cmd);
    if (text) write_text(tmp("api.scad"), text);
    ok(text && s.errors == 0 && rc == 0 && same_file(tmp("cli.scad"), tmp("api.scad")),
       "frep_export_scad: the same text as frep export");
    ok(text && strstr(text, "module my_model()"), "each named sub-expression a module");
    frep_free(text);
    o.fn = 12;
    text = src ? frep_export_scad(model, src, len, &o, collect, &s) : NULL;
    ok(text && strstr(text, "$fn = 12"), "$fn 12 is written");
    frep_free(text);
    o.fn = 2;
    s = (seen){ 0 };
    ok(!frep_export_scad(model, src, len, &o, collect, &s) && s.errors == 1,
       "$fn 2 is refused: %s", s.last);
    free(src);
    frep_program_free(p);

    const char *blend = "my_model(x[3], a[1]) {\n  my_model = x[1]^2 - x[2];\n}\n";
    frep_scad_options_init(&o);
    s = (seen){ 0 };
    text = frep_export_scad("q.hf", blend, strlen(blend), &o, collect, &s);
    ok(!text && s.errors == 2 && s.positioned == 1 && strstr(s.last, "q.hf"),
       "x[1]^2: an error at its position, then the failure (%s)", s.last);
}

/* The page of frep view for a mesh file and a cloud, and what it shows. */
static void test_view_page(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048];
    snprintf(model, sizeof model, "%s/examples/csg.hf", srcdir);
    seen s = { 0 };
    frep_mesh *m;
    frep_program *p = compile_and_mesh(model, 24, &s, &m);
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 500 --seed 3 --noise 0.01 -q -o '%s'", frep,
             model, tmp("v.xyz"));
    frep_cloud *c = run(cmd) == 0 ? frep_cloud_read(tmp("v.xyz"), collect, &s) : NULL;
    ok(m && c, "a mesh of examples/csg.hf and a cloud of 500 points");
    if (!m || !c) {
        frep_cloud_free(c);
        frep_mesh_free(m);
        frep_program_free(p);
        return;
    }

    /* distances to the model and to the mesh, and the scales */
    frep_distances dm, dt;
    int rm = frep_cloud_distances(c, m, p, 0, 1, &dm, collect, &s);
    int rt = frep_cloud_distances(c, m, NULL, 0, 2, &dt, collect, &s);
    ok(rm == 0 && rt == 0 && dm.point && dm.vertex && dt.point && dt.vertex,
       "frep_cloud_distances against the model and against the mesh");
    if (rm == 0 && rt == 0) {
        size_t n = frep_cloud_size(c), close = 0, inside = 0, agree = 0;
        for (size_t i = 0; i < n; i++) {
            close += fabs(dm.point[i]) < 0.2;
            inside += dm.point[i] > 0;
            agree += fabs(dm.point[i] - dt.point[i]) < 0.05;
        }
        ok(close >= n - n / 20 && inside > n / 5 && inside < 4 * n / 5,
           "noise 1%%: %zu of %zu points within 0.2, %zu inside", close, n, inside);
        ok(agree > 9 * n / 10, "the model's and the mesh's distances agree (%zu of %zu)", agree, n);
        size_t nv = frep_mesh_nverts(m), nonneg = 0;
        for (size_t j = 0; j < nv; j++) nonneg += dm.vertex[j] >= 0 && dm.vertex[j] == dt.vertex[j];
        ok(nonneg == nv, "the vertices' distances to the cloud: >= 0, the same both ways");
        double ps = dm.point_scale, m10 = ps;
        while (m10 >= 10) m10 /= 10;
        while (m10 < 1) m10 *= 10;
        ok(ps > 0 && dm.vertex_scale > 0 &&
               (fabs(m10 - 1) < 1e-9 || fabs(m10 - 2) < 1e-9 || fabs(m10 - 5) < 1e-9),
           "the scales are positive, 1, 2 or 5 x 10^k (points %g, surface %g)", ps,
           dm.vertex_scale);
    }

    /* the page against frep view of the mesh file (no timings in it) */
    frep_mesh_write(m, tmp("v.off"), FREP_MESH_AUTO, 0, collect, &s);
    frep_mesh *mr = frep_mesh_read(tmp("v.off"), collect, &s);
    frep_distances dr;
    memset(&dr, 0, sizeof dr);
    int rr = mr ? frep_cloud_distances(c, mr, NULL, 0, 1, &dr, collect, &s) : -1;
    frep_view_scene sc;
    frep_view_scene_init(&sc);
    ok(!sc.name && !sc.mesh && sc.npoints == 0 && !sc.pdist, "an empty scene");
    char name[512];
    snprintf(name, sizeof name, "%s", tmp("v.off"));  /* tmp()'s buffers are reused */
    sc.name = name;
    sc.info = "";                                     /* frep view's line for a mesh file */
    sc.mesh = mr;
    sc.npoints = frep_cloud_size(c);
    frep_cloud_arrays(c, &sc.px, &sc.py, &sc.pz, NULL, NULL, NULL);
    sc.pdist = dr.point;
    sc.pscale = dr.point_scale > 0 ? dr.point_scale : 1;
    sc.vdist = dr.vertex;
    sc.vscale = dr.vertex_scale > 0 ? dr.vertex_scale : 1;
    FILE *f = fopen(tmp("api.html"), "wb");
    int wr = rr == 0 && f ? frep_view_write_page(&sc, f, collect, &s) : -1;
    if (f) fclose(f);
    snprintf(cmd, sizeof cmd, "'%s' view '%s' --points '%s' -q -o '%s'", frep, tmp("v.off"),
             tmp("v.xyz"), tmp("cli.html"));
    ok(wr == 0 && run(cmd) == 0 && same_file(tmp("cli.html"), tmp("api.html")),
       "frep_view_write_page: the same page as frep view MESH --points");
    size_t plen = 0, jlen = 0;
    char *page = frep_view_page(&sc, 0, &plen, collect, &s);
    char *json = frep_view_scene_json(&sc, &jlen, collect, &s);
    size_t flen = 0;
    char *file = NULL;
    f = fopen(tmp("api.html"), "rb");
    if (f && fseek(f, 0, SEEK_END) == 0 && ftell(f) > 0) {
        flen = (size_t)ftell(f);
        rewind(f);
        file = malloc(flen);
        if (file && fread(file, 1, flen, f) != flen) flen = 0;
    }
    if (f) fclose(f);
    ok(page && file && plen == flen && memcmp(page, file, plen) == 0,
       "frep_view_page is the page written (%zu bytes)", plen);
    ok(json && jlen == strlen(json) && json[0] == '{' && strstr(json, "\"mesh\":{") &&
           strstr(json, "\"points\":{\"n\":500,") != NULL,
       "frep_view_scene_json: one object with the mesh (%zu bytes)", jlen);
    char *wpage = frep_view_page(&sc, 1, NULL, collect, &s);
    ok(wpage && strcmp(wpage, page) != 0, "a watching page differs (it polls its server)");
    ok(s.errors == 0, "no error on the way (%s)", s.errors ? s.last : "");
    frep_free(wpage);
    free(file);
    frep_free(json);
    frep_free(page);

    /* bad input: a mesh without triangles */
    frep_mesh *empty = frep_mesh_new(0, NULL, NULL, 0, NULL, collect, &s);
    seen e = { 0 };
    frep_distances de;
    ok(empty && frep_cloud_distances(c, empty, NULL, 0, 1, &de, collect, &e) == -1 &&
           e.errors == 1 && !de.point && !de.vertex,
       "a mesh without triangles: -1, an error (%s), nothing to free", e.last);
    frep_distances_free(&de);
    frep_distances_free(NULL);
    frep_mesh_free(empty);
    frep_distances_free(&dr);
    frep_distances_free(&dm);
    frep_distances_free(&dt);
    frep_mesh_free(mr);
    frep_cloud_free(c);
    frep_mesh_free(m);
    frep_program_free(p);
}

/* The server of frep view --watch: a GET routed, an unrouted one 404, a taken port. */
static void route_hello(void *user, const char *path, frep_view_reply *r)
{
    int *calls = user;
    ++*calls;
    if (strcmp(path, "/hello") == 0) *r = (frep_view_reply){ 200, "text/plain", "hi\n", 3 };
}

/* GET path from the server at port, stepping it until the reply is complete. */
static int http_get(frep_view_server *srv, int port, const char *path, int *calls, char *out,
                    size_t size)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_port = htons((uint16_t)port);
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        if (fd >= 0) close(fd);
        return -1;
    }
    char req[256];
    int n = snprintf(req, sizeof req, "GET %s HTTP/1.0\r\n\r\n", path);
    int answered = 0;
    if (send(fd, req, (size_t)n, 0) == n)
        for (int i = 0; i < 50 && !answered; i++)
            answered = frep_view_server_step(srv, 20, route_hello, calls) > 0;
    size_t got = 0;
    ssize_t k;
    while (answered && got + 1 < size && (k = recv(fd, out + got, size - 1 - got, 0)) > 0)
        got += (size_t)k;
    out[got] = '\0';
    close(fd);
    return answered ? 0 : -1;
}

static void test_view_server(void)
{
    seen s = { 0 };
    frep_view_server *srv = frep_view_server_open(0, collect, &s);
    int port = srv ? frep_view_server_port(srv) : 0;
    ok(srv && port > 0 && s.errors == 0, "a server on 127.0.0.1, port %d", port);
    if (!srv) return;
    int calls = 0;
    ok(frep_view_server_step(srv, 0, route_hello, &calls) == 0 && calls == 0,
       "a step without clients answers nothing");
    char reply[512];
    ok(http_get(srv, port, "/hello", &calls, reply, sizeof reply) == 0 && calls == 1 &&
           strncmp(reply, "HTTP/1.0 200", 12) == 0 && strstr(reply, "\r\n\r\nhi\n"),
       "GET /hello: 200 and the routed body");
    ok(http_get(srv, port, "/nope", &calls, reply, sizeof reply) == 0 && calls == 2 &&
           strncmp(reply, "HTTP/1.0 404", 12) == 0,
       "GET /nope: 404 when the route leaves the reply");
    seen e = { 0 };
    frep_view_server *two = frep_view_server_open(port, collect, &e);
    ok(!two && e.errors == 1, "the same port again: NULL and an error (%s)", e.last);
    frep_view_server_close(two);
    frep_view_server_close(srv);
    frep_view_server_close(NULL);
}

/* Write a mesh with colours through frep_mesh_write_stream, as the command does. */
static int write_stream(const frep_mesh *m, const uint8_t *rgb, const char *path,
                        frep_mesh_format fmt, int ascii)
{
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int rc = frep_mesh_write_stream(m, rgb, f, fmt, ascii);
    return fclose(f) != 0 ? -1 : rc;
}

/* The first line of the command's standard output holding `key`, into line. */
static int command_line(const char *cmd, const char *key, char *line, size_t size)
{
    FILE *p = popen(cmd, "r");
    int found = 0;
    while (p && !found && fgets(line, (int)size, p)) found = strstr(line, key) != NULL;
    if (p) pclose(p);
    return found;
}

static volatile sig_atomic_t stop_flag;

/* What frep mesh, sample and render need of the API beyond polygonizing and writing
 * (they run on frep.h alone): mesh formats by name, coloured PLY and VRML to a stream,
 * hfp's per-axis grid, the --check distances and -v's counts, the cancel flag, clouds
 * to a stream, the views -- each against the command's own output. */
static void test_mesh_command(const char *frep, const char *srcdir)
{
    char model[600], cmd[2048], line[1024];
    seen s = { 0 };

    ok(frep_mesh_format_for_path("a/b.wrl") == FREP_MESH_WRL &&
           frep_mesh_format_for_path("B.STL") == FREP_MESH_STL &&
           frep_mesh_format_for_path("c.ply") == FREP_MESH_PLY &&
           frep_mesh_format_for_path("c.xyz") == FREP_MESH_AUTO &&
           frep_mesh_format_for_path(NULL) == FREP_MESH_AUTO,
       "frep_mesh_format_for_path: by the extension, AUTO for none");
    ok(strcmp(frep_mesh_format_name(FREP_MESH_WRL), "VRML") == 0 &&
           strcmp(frep_mesh_format_name(FREP_MESH_OFF), "OFF") == 0 &&
           strcmp(frep_mesh_format_name(FREP_MESH_AUTO), "unknown") == 0,
       "frep_mesh_format_name: VRML, OFF, unknown");
    ok(frep_render_view_ok("top") && frep_render_view_ok("side") && !frep_render_view_ok("upside") &&
           !frep_render_view_ok(NULL),
       "frep_render_view_ok: top and side, not upside");

    /* the model's colours into PLY and VRML, as frep mesh -b 1 -g 24 */
    snprintf(model, sizeof model, "%s/tests/models/color_sphere.hf", srcdir);
    size_t len = 0;
    char *text = slurp(model, &len);
    frep_program *p = text ? frep_compile(model, text, len, NULL, collect, &s) : NULL;
    free(text);
    frep_mesh_options o;
    frep_mesh_options_init(&o);
    ok(o.grid_axes[0] == 0 && o.grid_axes[1] == 0 && o.grid_axes[2] == 0 && !o.cancel_flag,
       "mesh defaults: no per-axis grid, no cancel flag");
    o.has_box = 1;
    for (int k = 0; k < 3; k++) {
        o.box[k] = -1;
        o.box[k + 3] = 1;
    }
    o.grid = 24;
    frep_mesh *m = p ? frep_polygonize(p, &o, NULL, collect, &s) : NULL;
    uint8_t *rgb = NULL;
    ok(m && frep_mesh_colors(p, m, 2.0 / 24, 0, NULL, 1, &rgb, NULL) == 0 && rgb,
       "color_sphere.hf: a mesh with colours");
    static const char *cext[] = { "ply", "wrl" };
    for (int k = 0; k < 2; k++) {
        char a[64], b[64];
        snprintf(a, sizeof a, "clic.%s", cext[k]);
        snprintf(b, sizeof b, "apic.%s", cext[k]);
        snprintf(cmd, sizeof cmd, "'%s' mesh '%s' -b 1 -g 24 -q -o '%s'", frep, model, tmp(a));
        int rc = run(cmd);
        ok(rc == 0 && rgb &&
               write_stream(m, rgb, tmp(b), frep_mesh_format_for_path(b), 0) == 0 &&
               same_file(tmp(a), tmp(b)),
           "frep mesh -o .%s with the model's colours: the same bytes", cext[k]);
    }
    ok(m && write_stream(m, NULL, tmp("bad.stl"), FREP_MESH_AUTO, 0) == -1,
       "frep_mesh_write_stream refuses FREP_MESH_AUTO");
    /* the same VRML through the path writer, without colours: hfp's default material */
    snprintf(cmd, sizeof cmd, "'%s' mesh '%s' -b 1 -g 24 --color none -q -o '%s'", frep, model,
             tmp("clin.wrl"));
    ok(run(cmd) == 0 && m && frep_mesh_write(m, tmp("apin.wrl"), FREP_MESH_AUTO, 0, collect, &s) == 0 &&
           same_file(tmp("clin.wrl"), tmp("apin.wrl")),
       "frep_mesh_write .wrl: the bytes of frep mesh --color none");
    frep_free(rgb);
    frep_mesh_free(m);
    frep_program_free(p);

    /* hfp's -g NX,NY,NZ, the --check distances and -v's counts */
    snprintf(model, sizeof model, "%s/examples/csg.hf", srcdir);
    text = slurp(model, &len);
    p = text ? frep_compile(model, text, len, NULL, collect, &s) : NULL;
    free(text);
    frep_mesh_options_init(&o);
    o.grid = 30;
    o.grid_axes[0] = 20;
    o.grid_axes[1] = 25;
    o.grid_axes[2] = 30;
    frep_mesh_info info;
    m = p ? frep_polygonize(p, &o, &info, collect, &s) : NULL;
    snprintf(cmd, sizeof cmd, "'%s' mesh '%s' -g 20,25,30 -q -o '%s'", frep, model, tmp("clig.stl"));
    int rc = run(cmd);
    ok(rc == 0 && m && frep_mesh_write(m, tmp("apig.stl"), FREP_MESH_AUTO, 0, collect, &s) == 0 &&
           same_file(tmp("clig.stl"), tmp("apig.stl")),
       "grid_axes 20,25,30: the bytes of frep mesh -g 20,25,30");
    snprintf(cmd, sizeof cmd, "'%s' mesh '%s' -g 20,25,30 -v --check -o '%s'", frep, model,
             tmp("clig.stl"));
    char want[256];
    snprintf(want, sizeof want, "%zu face vertices, %zu vertices settled", info.face_vertices,
             info.settled);
    ok(m && command_line(cmd, "work:", line, sizeof line) && strstr(line, want),
       "info.settled: %zu, as frep mesh -v", info.settled);
    frep_mesh_distance md;
    ok(m && frep_mesh_surface_distance(p, &o, m, FREP_MESH_SURFACE_TOL, &md, collect, &s) == 0,
       "frep_mesh_surface_distance: measured");
    snprintf(want, sizeof want, "from the surface %zu (largest %.3g cell)", md.far, md.max_dist);
    ok(m && command_line(cmd, "self-intersecting", line, sizeof line) && strstr(line, want),
       "frep_mesh_surface_distance: %s, as frep mesh --check", want);
    /* a tighter tolerance counts more vertices far */
    frep_mesh_distance tight;
    memset(&tight, 0, sizeof tight);
    int trc = m ? frep_mesh_surface_distance(p, &o, m, md.max_dist / 2, &tight, NULL, NULL) : -1;
    ok(trc == 0 && tight.far > md.far,
       "half the largest distance as the tolerance: %zu vertices far (%zu at %g)", tight.far,
       md.far, FREP_MESH_SURFACE_TOL);
    frep_mesh_free(m);

    /* the cancel flag: NULL, nothing reported */
    stop_flag = 1;
    o.cancel_flag = &stop_flag;
    seen c = { 0 };
    info.interrupted = 0;
    ok(p && !frep_polygonize(p, &o, &info, collect, &c) && info.interrupted && c.errors == 0 &&
           c.warnings == 0,
       "a raised cancel flag: no mesh, info.interrupted, nothing reported");
    frep_sample_options so;
    frep_sample_options_init(&so);
    so.n = 200;
    so.mesh.cancel_flag = &stop_flag;
    ok(p && !frep_sample(p, &so, collect, &c) && c.errors == 0,
       "frep_sample with a raised cancel flag: no cloud, nothing reported");
    stop_flag = 0;

    /* a cloud to a stream: the bytes of frep_cloud_write, by the name's extension */
    frep_cloud *cl = p ? frep_sample(p, &so, collect, &s) : NULL;
    for (int k = 0; k < 2; k++) {
        const char *a = k ? "apis.ply" : "apis.xyz", *b = k ? "apit.ply" : "apit.xyz";
        FILE *f = fopen(tmp(b), "wb");
        int w = f && cl ? frep_cloud_write_stream(cl, f, b) : -1;
        if (f && fclose(f) != 0) w = -1;
        ok(cl && w == 0 && frep_cloud_write(cl, tmp(a), collect, &s) == 0 &&
               same_file(tmp(a), tmp(b)),
           "frep_cloud_write_stream %s: the bytes of frep_cloud_write", b);
    }
    frep_cloud_free(cl);
    frep_program_free(p);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");
}

/* Whether two text files hold the same lines but those containing `except`. */
static int same_but(const char *a, const char *b, const char *except)
{
    size_t la = 0, lb = 0;
    char *ta = slurp(a, &la), *tb = slurp(b, &lb);
    int same = ta && tb;
    char *x = ta, *y = tb;
    while (same && x && y) {
        char *ex = strchr(x, '\n'), *ey = strchr(y, '\n');
        if (ex) *ex = '\0';
        if (ey) *ey = '\0';
        if (!(strstr(x, except) && strstr(y, except))) same = strcmp(x, y) == 0;
        x = ex ? ex + 1 : NULL;
        y = ey ? ey + 1 : NULL;
        if (!x != !y) same = 0;
    }
    free(ta);
    free(tb);
    return same && la > 0;
}

typedef struct evolve_calls {
    int progress, cancel, stop_at;
    uint32_t last_generation;
    int phase;               /* of the last report */
    int stop_phase;          /* >= 0: cancel once a report of this phase came */
    unsigned seen;           /* 1 << phase of every report */
    struct trace_lines *trace; /* on_trace's */
} evolve_calls;

static void evolve_progress(void *user, const frep_evolve_progress *p)
{
    evolve_calls *c = user;
    c->progress++;
    c->last_generation = p->generation;
    c->phase = p->phase;
    c->seen |= 1u << p->phase;
}

static int evolve_cancel(void *user)
{
    evolve_calls *c = user;
    if (c->stop_phase >= 0) return (c->seen >> c->stop_phase) & 1u;
    return ++c->cancel >= c->stop_at;
}

/* A cancel in each phase of a partitioned run (4 the clique GAs, 1 the merges, 2 the
 * merged tree, 3 its growth, 5 the final simplification; 0 a GA generation): the
 * result is kept, marked interrupted, and its model compiles and evaluates. */
static void test_evolve_cancel_phases(frep_cloud *c, const frep_segmentation *pr)
{
    static const int phases[] = { 4, 1, 2, 3, 0, 5 };
    frep_evolve_options o;
    frep_evolve_options_init(&o);
    o.seed = 3;
    o.population = 60;
    o.generations = 40;
    o.progress = evolve_progress;
    o.cancel = evolve_cancel;
    for (size_t k = 0; k < sizeof phases / sizeof phases[0]; k++) {
        seen s = { 0 };
        evolve_calls calls = { 0, 0, 1 << 30, 0, -1, phases[k], 0, NULL };
        o.user = &calls;
        /* phase 5 comes after a GA over all primitives (no partition) */
        o.partition = phases[k] != 5;
        frep_evolution *e = frep_evolve(c, pr, &o, collect, &s);
        frep_evolve_info in = { 0 };
        if (e) frep_evolution_get_info(e, &in);
        int compiles = 0;
        double v = NAN;
        if (e && frep_evolution_write(e, tmp("phase.hf"), NULL, NULL, 0, 0, collect, &s) == 0) {
            char *src = NULL;
            size_t len = 0;
            FILE *f = fopen(tmp("phase.hf"), "rb");
            if (f) {
                src = malloc(1 << 20);
                if (src) len = fread(src, 1, (1 << 20) - 1, f);
                fclose(f);
            }
            frep_program *p = src ? frep_compile("phase.hf", src, len, NULL, NULL, NULL) : NULL;
            frep_scratch *sc = p ? frep_scratch_new(p) : NULL;
            if (sc) {
                /* at the cloud's first point, on the surface */
                const double *cx, *cy, *cz;
                frep_cloud_arrays(c, &cx, &cy, &cz, NULL, NULL, NULL);
                double x = cx[0], y = cy[0], z = cz[0];
                compiles = frep_eval(p, sc, 1, &x, &y, &z, NULL, &v) == 0;
            }
            frep_scratch_free(sc);
            frep_program_free(p);
            free(src);
        }
        ok(e && in.interrupted && in.tree_size > 0 && ((calls.seen >> phases[k]) & 1u) &&
               compiles && isfinite(v),
           "cancel in phase %d: interrupted %d, a tree of %u nodes, its model evaluates (%g)",
           phases[k], in.interrupted, in.tree_size, v);
        frep_evolution_free(e);
    }
}

/* frep evolve and frep_evolve on the same cloud, primitives and seed: the same model
 * but for the line with the run's seconds; a cancel keeps the best tree so far. */
static void test_evolve(const char *frep, const char *srcdir)
{
    char model[600], cmd[3072], line[2048];
    snprintf(model, sizeof model, "%s/tests/models/segment_box.hf", srcdir);
    seen s = { 0 };
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 3000 --seed 6 -q -o '%s'", frep, model,
             tmp("ev.xyz"));
    ok(run(cmd) == 0, "a box cloud with normals from frep sample");
    snprintf(cmd, sizeof cmd, "'%s' segment '%s' --seed 2 -q -o '%s'", frep, tmp("ev.xyz"),
             tmp("ev.fit"));
    ok(run(cmd) == 0, "its primitives from frep segment");
    /* the command line as frep evolve records it in the model */
    snprintf(line, sizeof line, "evolve %s -p %s --seed 3 --population 60 --generations 40 "
             "-q -o %s", tmp("ev.xyz"), tmp("ev.fit"), tmp("cli.ev.hf"));
    snprintf(cmd, sizeof cmd, "'%s' %s", frep, line);
    ok(run(cmd) == 0, "frep evolve -p --seed 3");
    char command[2100];
    snprintf(command, sizeof command, "frep %s", line);

    frep_evolve_options o;
    frep_evolve_options_init(&o);
    ok(o.seed == 1 && o.setops == FREP_SETOPS_MINMAX && o.partition == 1 && o.population == 150 &&
           o.alpha_deg == 0 && !o.cancel, "evolve defaults: seed 1, minmax, partitioned, "
           "population 150, automatic alpha");
    o.seed = 3;
    o.population = 60;
    o.generations = 40;
    evolve_calls calls = { 0, 0, 1 << 30, 0, -1, -1, 0, NULL };
    o.progress = evolve_progress;
    o.cancel = evolve_cancel;
    o.user = &calls;
    frep_cloud *c = frep_cloud_read(tmp("ev.xyz"), collect, &s);
    frep_segmentation *pr = frep_segmentation_read(tmp("ev.fit"), collect, &s);
    ok(pr && frep_segmentation_nprims(pr) >= 6 && !frep_segmentation_labels(pr),
       "frep_segmentation_read: %zu primitives, no labels", pr ? frep_segmentation_nprims(pr) : 0);
    frep_evolution *e = c && pr ? frep_evolve(c, pr, &o, collect, &s) : NULL;
    frep_evolve_info in = { 0 };
    if (e) frep_evolution_get_info(e, &in);
    ok(e && in.tree_size >= 11 && in.npoints == 3000 && in.explained > 2900 && !in.interrupted,
       "frep_evolve: a tree of %u nodes explains %zu of %zu points", in.tree_size, in.explained,
       in.npoints);
    ok(calls.progress > 0 && calls.cancel >= calls.progress,
       "progress called %d times, cancel polled %d times (with each report, and between)",
       calls.progress, calls.cancel);
    ok(e && frep_evolution_write(e, tmp("api.ev.hf"), command, tmp("ev.xyz"), 0, 0, collect,
                                 &s) == 0 &&
           same_but(tmp("cli.ev.hf"), tmp("api.ev.hf"), " generations, "),
       "the same model as frep evolve (but the run's seconds)");
    ok(e && frep_evolution_write_dot(e, tmp("api.dot"), collect, &s) == 0,
       "the tree for Graphviz written");
    frep_evolution_free(e);

    /* no partition, cancelled at the fifth poll: the best tree of 5 generations */
    o.partition = 0;
    o.stagnation = 1000000;
    o.generations = 1000000;
    calls = (evolve_calls){ 0, 0, 5, 0, -1, -1, 0, NULL };
    e = c && pr ? frep_evolve(c, pr, &o, collect, &s) : NULL;
    if (e) frep_evolution_get_info(e, &in);
    ok(e && in.interrupted && calls.cancel == 5 && in.generations <= 6 && in.tree_size > 0,
       "cancelled at the fifth poll: %u generations, a tree of %u nodes",
       e ? in.generations : 0, e ? in.tree_size : 0);
    ok(e && frep_evolution_write(e, tmp("cut.hf"), NULL, NULL, 0, 0, collect, &s) == 0,
       "its model written");
    frep_evolution_free(e);
    if (c && pr) test_evolve_cancel_phases(c, pr);
    frep_segmentation_free(pr);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");

    seen er = { 0 };
    ok(!frep_segmentation_read(tmp("nothing.fit"), collect, &er) && er.errors == 1,
       "a missing primitive list: an error (%s)", er.last);
    frep_cloud_free(c);
}

/* Trace lines collected, and a line's fields but the wall and CPU seconds. */
typedef struct trace_lines {
    char text[1 << 16];
    size_t len;
    int lines;
} trace_lines;

static void on_trace(void *user, const char *line)
{
    trace_lines *t = ((evolve_calls *)user)->trace;
    size_t n = strlen(line);
    if (t->len + n < sizeof t->text) {
        memcpy(t->text + t->len, line, n + 1);
        t->len += n;
    }
    t->lines++;
}

/* Whether two traces agree but for their times: the same lines, in order, each line
 * the same with its 2nd and 3rd fields (wall, CPU) and the end line's times dropped. */
static int same_trace(const char *a, const char *b)
{
    char x[4096], y[4096];
    int same = *a && *b;
    while (same && *a && *b) {
        size_t la = strcspn(a, "\n"), lb = strcspn(b, "\n");
        snprintf(x, sizeof x, "%.*s", (int)la, a);
        snprintf(y, sizeof y, "%.*s", (int)lb, b);
        if (strncmp(x, "# end:", 6) == 0 && strncmp(y, "# end:", 6) == 0) {
            const char *nx = strstr(x, " CPU,"), *ny = strstr(y, " CPU,");
            same = nx && ny && strcmp(nx, ny) == 0;
        } else if (x[0] != '#') {
            char g1[64], g2[64], rest1[512], rest2[512];
            double w, c;
            same = sscanf(x, "%63s %lf %lf %511[^\n]", g1, &w, &c, rest1) == 4 &&
                   sscanf(y, "%63s %lf %lf %511[^\n]", g2, &w, &c, rest2) == 4 &&
                   strcmp(g1, g2) == 0 && strcmp(rest1, rest2) == 0;
        } else {
            same = strcmp(x, y) == 0;
        }
        a += la + (a[la] == '\n');
        b += lb + (b[lb] == '\n');
    }
    return same && !*a && !*b;
}

static const char block_hf[] =
    "-- @setops minmax\n"
    "-- @box -1.5 -1.5 -1 1.5 1.5 1\n"
    "my_model(x[3], a[1])\n{\n"
    "    my_model = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &\n"
    "               frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);\n"
    "}\n";

/* frep evolve --residual --trace and frep_evolve with a base and a trace callback: the
 * same model and trace but for the times; the residual points segmented without
 * primitives; --stop-share; a base refused. */
static void test_evolve_residual(const char *frep)
{
    seen s = { 0 };
    char cmd[3072], line[2048], command[2100];
    write_text(tmp("block.hf"), block_hf);
    write_text(tmp("hole.hf"), "-- @setops minmax\n-- @box -1.5 -1.5 -1 1.5 1.5 1\n"
               "my_model(x[3], a[1])\n{\n"
               "    blk = frPlane(x, 1, 0, 0, 1) & frPlane(x, -1, 0, 0, 1) & frPlane(x, 0, 1, 0, 1) &\n"
               "          frPlane(x, 0, -1, 0, 1) & frPlane(x, 0, 0, 1, 0.5) & frPlane(x, 0, 0, -1, 0.5);\n"
               "    my_model = blk \\ frCylinder(x, 0.2, 0.1, 0, 0, 0, 1, 0.4);\n}\n");
    write_text(tmp("hole.fit"), "sphere 3 3 3 1\ncylinder 0 0 1 0.2 0.1 0 0.4\n");
    snprintf(cmd, sizeof cmd, "'%s' sample '%s' -n 4000 --seed 1 -q -o '%s'", frep,
             tmp("hole.hf"), tmp("hole.xyz"));
    ok(run(cmd) == 0, "a block with a hole, sampled");
    char out[600];   /* tmp() keeps 4 paths at once */
    snprintf(out, sizeof out, "%s", tmp("cli.r1.hf"));
    snprintf(line, sizeof line, "evolve %s --residual %s -p %s --seed 1 --trace %s -q -o %s",
             tmp("hole.xyz"), tmp("block.hf"), tmp("hole.fit"), tmp("cli.trace"), out);
    snprintf(cmd, sizeof cmd, "'%s' %s", frep, line);
    ok(run(cmd) == 0, "frep evolve --residual -p --trace");
    snprintf(command, sizeof command, "frep %s", line);

    frep_program *p = frep_compile(tmp("block.hf"), block_hf, strlen(block_hf), NULL, collect, &s);
    frep_evolve_base *b = p ? frep_evolve_base_new(p, tmp("block.hf"), block_hf,
                                                   strlen(block_hf), NULL, collect, &s) : NULL;
    ok(b && frep_evolve_base_setops(b) == FREP_SETOPS_MINMAX,
       "frep_evolve_base_new: the block, min/max like its file");
    frep_cloud *c = frep_cloud_read(tmp("hole.xyz"), collect, &s);
    frep_segmentation *pr = frep_segmentation_read(tmp("hole.fit"), collect, &s);
    frep_evolve_options o;
    frep_evolve_options_init(&o);
    ok(!o.trace && o.stop_share == 0 && !o.base, "no trace, stop share or base by default");
    o.seed = 1;
    o.base = b;
    o.setops = FREP_SETOPS_RFUNC;      /* the base's replace it */
    static trace_lines tl;
    evolve_calls calls = { 0, 0, 1 << 30, 0, -1, -1, 0, &tl };
    o.progress = evolve_progress;
    o.trace = on_trace;
    o.user = &calls;
    frep_evolution *e = b && c && pr ? frep_evolve(c, pr, &o, collect, &s) : NULL;
    frep_evolve_info in = { 0 };
    if (e) frep_evolution_get_info(e, &in);
    if (!e) diag("frep_evolve: %s", s.last);
    ok(e && in.base_explained > 3000 && in.base_explained < 4000 && in.base_failed == 0 &&
           in.explained == 4000,
       "the base explains %zu of 4000 points, the joined tree %zu", in.base_explained,
       in.explained);
    ok(((calls.seen >> FREP_EVOLVE_SEARCH) & 1u) && !((calls.seen >> FREP_EVOLVE_SEGMENT) & 1u) &&
           !((calls.seen >> FREP_EVOLVE_NORMALS) & 1u),
       "phases: the search started; no segmentation or normals (given)");
    size_t len = 0;
    char *hf = e ? frep_evolution_model(e, command, tmp("hole.xyz"), 0, 0, &len, collect, &s) : NULL;
    FILE *f = fopen(tmp("api.r1.hf"), "wb");
    if (f && hf) fwrite(hf, 1, len, f);
    if (f) fclose(f);
    ok(hf && len == strlen(hf) && strstr(hf, "base_model(x, a)") &&
           same_but(tmp("cli.r1.hf"), tmp("api.r1.hf"), " generations, "),
       "frep_evolution_model: the joined model of frep evolve --residual (but the seconds)");
    frep_free(hf);
    size_t cl = 0;
    char *ct = slurp(tmp("cli.trace"), &cl);
    ok(ct && tl.lines > 5 && strncmp(tl.text, "# frep evolve trace, seed 1\n", 28) == 0 &&
           same_trace(ct, tl.text),
       "the trace callback: %d lines, those of --trace but for the times", tl.lines);
    free(ct);
    ct = NULL;
    char *dot = e ? frep_evolution_dot(e, &len, collect, &s) : NULL;
    ok(e && dot && frep_evolution_write_dot(e, tmp("r1.dot"), collect, &s) == 0 &&
           (ct = slurp(tmp("r1.dot"), &cl)) && cl == len && memcmp(ct, dot, len) == 0,
       "frep_evolution_dot: the text frep_evolution_write_dot writes");
    free(ct);
    frep_free(dot);
    frep_evolution_free(e);

    /* without primitives: the residual points alone are segmented */
    calls = (evolve_calls){ 0, 0, 1 << 30, 0, -1, -1, 0, NULL };
    o.trace = NULL;
    e = b && c ? frep_evolve(c, NULL, &o, collect, &s) : NULL;
    if (e) frep_evolution_get_info(e, &in);
    ok(e && ((calls.seen >> FREP_EVOLVE_SEGMENT) & 1u) && in.nprims > 0 && in.explained > 3960,
       "no primitives: the residual segmented (%zu primitives), %zu of 4000 explained",
       in.nprims, in.explained);
    frep_evolution_free(e);

    /* stop_share: the GA ends at the first generation explaining half the points */
    o.base = NULL;
    o.partition = 0;
    o.trace = on_trace;
    tl.len = 0;
    tl.lines = 0;
    tl.text[0] = '\0';
    calls = (evolve_calls){ 0, 0, 1 << 30, 0, -1, -1, 0, &tl };
    o.stop_share = 50;
    write_text(tmp("faces.fit"), "plane 1 0 0 1\nplane -1 0 0 1\nplane 0 1 0 1\n"
               "plane 0 -1 0 1\nplane 0 0 1 0.5\nplane 0 0 -1 0.5\ncylinder 0 0 1 0.2 0.1 0 0.4\n");
    frep_segmentation *faces = frep_segmentation_read(tmp("faces.fit"), collect, &s);
    e = c && faces ? frep_evolve(c, faces, &o, collect, &s) : NULL;
    frep_segmentation_free(faces);
    int hits = 0, lines = 0;
    double last = -1;
    for (const char *q = tl.text; *q; q += strcspn(q, "\n") + (q[strcspn(q, "\n")] != 0)) {
        if (*q == '#') continue;
        double w, cpu, fit, share;
        unsigned gen, size;
        if (sscanf(q, "%u %lf %lf %lf %u %lf", &gen, &w, &cpu, &fit, &size, &share) == 6) {
            lines++;
            hits += share >= 50;
            last = share;
        }
    }
    ok(e && lines > 0 && hits == 1 && last >= 50,
       "stop_share 50: %d generations, the last explains %g%%", lines, last);
    frep_evolution_free(e);

    seen er = { 0 };
    static const char flat[] = "my_model(x[2], a[1]) { my_model = 1 - x[1]*x[1]; }\n";
    frep_program *p2 = frep_compile("flat.hf", flat, strlen(flat), NULL, collect, &er);
    ok(p2 && !frep_evolve_base_new(p2, "flat.hf", flat, strlen(flat), NULL, collect, &er) &&
           er.errors == 1 && strstr(er.last, "3D"),
       "a 2D model is no base: an error (%s)", er.last);
    frep_program_free(p2);
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");
    frep_segmentation_free(pr);
    frep_cloud_free(c);
    frep_evolve_base_free(b);
    frep_program_free(p);
}

/* A whole file into a malloc'ed NUL-terminated string (NULL when it cannot be read). */
static char *read_text(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16, n = 0;
    char *s = malloc(cap);
    while (s) {
        n += fread(s + n, 1, cap - 1 - n, f);
        if (n < cap - 1) break;
        char *t = realloc(s, 2 * cap);
        if (!t) {
            free(s);
            s = NULL;
        }
        s = t;
        cap *= 2;
    }
    fclose(f);
    if (s) s[n] = '\0';
    if (len) *len = n;
    return s;
}

/* frep_print_source: the text frep print prints, NULL on a syntax error and, with
 * strict, on what HyperFun rejects. */
static void test_print_source(const char *frep, const char *srcdir)
{
    static const char *models[] = { "csg", "blend", "twist" };
    char path[600], cmd[2048];
    for (int k = 0; k < 3; k++) {
        snprintf(path, sizeof path, "%s/examples/%s.hf", srcdir, models[k]);
        size_t len = 0, outlen = 0;
        char *text = read_text(path, &len);
        seen s = { 0 };
        char *out = text ? frep_print_source(path, text, len, k == 1, &outlen, collect, &s) : NULL;
        snprintf(cmd, sizeof cmd, "'%s' print %s '%s' > '%s' 2>/dev/null", frep,
                 k == 1 ? "--strict" : "", path, tmp("cli_print.hf"));
        int rc = system(cmd);
        if (out) write_text(tmp("api_print.hf"), out);
        ok(rc == 0 && out && outlen == strlen(out) && s.errors == 0 &&
               same_file(tmp("cli_print.hf"), tmp("api_print.hf")),
           "frep_print_source%s: the text of frep print%s on examples/%s.hf",
           k == 1 ? " strict" : "", k == 1 ? " --strict" : "", models[k]);
        frep_free(out);
        free(text);
    }

    static const char syntax[] = "my_model(x[3], a[1])\n{\n    my_model = ;\n}\n";
    seen s = { 0 };
    size_t outlen = 7;
    char *out = frep_print_source("bad.hf", syntax, strlen(syntax), 0, &outlen, collect, &s);
    ok(!out && outlen == 0 && s.errors == 1 && s.positioned == 1,
       "frep_print_source: a syntax error is reported with its position, NULL (%s)", s.last);

    /* the value assigned in a branch: frep accepts it, the reference interpreter not */
    static const char nothf[] = "my_model(x[3], a[1])\n{\n"
                                "    if x[1] > 0 then my_model = 1; else my_model = 2; endif;\n}\n";
    seen w = { 0 };
    out = frep_print_source("w.hf", nothf, strlen(nothf), 0, NULL, collect, &w);
    ok(out && strstr(out, "my_model = 2") && w.errors == 0,
       "frep_print_source: not HyperFun, but printed without strict");
    frep_free(out);
    seen e = { 0 };
    out = frep_print_source("w.hf", nothf, strlen(nothf), 1, NULL, collect, &e);
    ok(!out && e.errors >= 1 && strstr(e.last, "not HyperFun"),
       "frep_print_source strict: an error, NULL (%s)", e.last);
    frep_free(out);
}

/* frep_eval_grid: the figures frep eval --grid prints, the same with or without
 * pruning and at any thread count; its limits. */
static void test_eval_grid(const char *frep, const char *srcdir)
{
    char path[600], cmd[2048], want[256];
    snprintf(path, sizeof path, "%s/examples/csg.hf", srcdir);
    size_t len = 0;
    char *text = read_text(path, &len);
    seen s = { 0 };
    frep_program *p = text ? frep_compile(path, text, len, NULL, collect, &s) : NULL;
    free(text);
    ok(p != NULL, "examples/csg.hf compiles");
    if (!p) return;

    frep_grid_options o;
    frep_grid_options_init(&o);
    ok(o.n == 64 && o.prune == 1 && o.single == 0 && o.has_box == 0,
       "frep_grid_options_init: 64 points per axis, pruning, double");
    o.n = 33;
    o.nthreads = 2;
    frep_grid_summary g;
    int rc = frep_eval_grid(p, &o, &g, collect, &s);
    snprintf(cmd, sizeof cmd, "'%s' eval --grid 33 -t 2 '%s' > '%s' 2>/dev/null", frep, path,
             tmp("grid.txt"));
    int crc = system(cmd);
    char *got = read_text(tmp("grid.txt"), NULL);
    int same = rc == 0 && crc == 0 && got != NULL;
    double npts = (double)g.points;
    snprintf(want, sizeof want, "grid      33^3 = %.0f points over [%g,%g]x[%g,%g]x[%g,%g]\n",
             npts, g.box[0], g.box[3], g.box[1], g.box[4], g.box[2], g.box[5]);
    same = same && strstr(got, want);
    snprintf(want, sizeof want, "inside    %llu (%.6f of the points, f >= 0)\n",
             (unsigned long long)g.inside, (double)g.inside / npts);
    same = same && strstr(got, want);
    snprintf(want, sizeof want, "values    min %.9g  max %.9g  sum %.9g\n", g.min, g.max, g.sum);
    same = same && strstr(got, want);
    snprintf(want, sizeof want, "nan       %llu\n", (unsigned long long)g.nans);
    same = same && strstr(got, want);
    snprintf(want, sizeof want, "%.1f evaluated per point on average (interval pruning)",
             g.insns / npts);
    same = same && strstr(got, want);
    ok(same && g.points == 33 * 33 * 33 && g.inside > 0 && g.inside < g.points,
       "frep_eval_grid: the figures of frep eval --grid 33 (%llu inside)",
       (unsigned long long)g.inside);
    free(got);

    frep_grid_summary w;
    o.prune = 0;
    o.nthreads = 1;
    rc = frep_eval_grid(p, &o, &w, collect, &s);
    ok(rc == 0 && w.inside == g.inside && w.nans == g.nans && w.sum == g.sum &&
           w.min == g.min && w.max == g.max && w.insns >= g.insns && w.threads == 1,
       "without pruning on one thread: the same figures, no fewer instructions (%.0f, %.0f)",
       w.insns, g.insns);

    o.prune = 1;
    o.single = 1;
    rc = frep_eval_grid(p, &o, &w, collect, &s);
    ok(rc == 0 && w.inside == g.inside && w.nans == g.nans && w.precision != FREP_GRID_DOUBLE &&
           (w.precision == FREP_GRID_SINGLE || (w.single_blocks == 0 && w.redone_blocks == 0)),
       "single precision: the inside count of double (precision %d, %llu blocks in float)",
       w.precision, (unsigned long long)w.single_blocks);

    o.single = 0;
    o.has_box = 1;
    const double box[6] = { -1, -2, -3, 1, 2, 3 };
    memcpy(o.box, box, sizeof box);
    rc = frep_eval_grid(p, &o, &w, collect, &s);
    ok(rc == 0 && memcmp(w.box, box, sizeof box) == 0 && w.inside != g.inside,
       "a box of the options is the box evaluated");

    frep_grid_summary d;
    rc = frep_eval_grid(p, NULL, &d, collect, &s);
    ok(rc == 0 && d.points == 64 * 64 * 64 && memcmp(d.box, g.box, sizeof box) == 0 &&
           d.precision == FREP_GRID_DOUBLE,
       "NULL options: 64^3 points over the model's box");
    ok(s.errors == 0, "no error reported on the way (%s)", s.errors ? s.last : "");

    long bad[2] = { FREP_GRID_MIN_N - 1, FREP_GRID_MAX_N + 1 };
    for (int k = 0; k < 2; k++) {
        seen e = { 0 };
        frep_grid_options_init(&o);
        o.n = bad[k];
        rc = frep_eval_grid(p, &o, &d, collect, &e);
        ok(rc == -1 && e.errors == 1 && strstr(e.last, "points per axis"),
           "a grid of %ld points per axis: an error (%s)", bad[k], e.last);
    }
    frep_program_free(p);

    /* runtime errors are counted, not reported: the caller reports them */
    seen r = { 0 };
    p = compile("my_model(x[3], a[1])\n{\n    my_model = sqrt(x[1]) - 1;\n}\n", &r);
    frep_grid_options_init(&o);
    o.n = 8;
    rc = p ? frep_eval_grid(p, &o, &g, collect, &r) : -1;
    ok(rc == 0 && g.errors.count == g.nans && g.nans == 4 * 8 * 8 && g.errors.what &&
           r.errors == 0 && r.warnings == 0,
       "sqrt of negative x: %llu NaN points, the errors in the summary",
       (unsigned long long)g.nans);
    frep_program_free(p);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "%s/frep-api.XXXXXX", getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) {
        printf("Bail out! cannot make a temporary directory\n");
        return 1;
    }
    test_version();
    test_params();
    test_interval();
    test_cloud();
    test_mesh();
    test_mesh_colors();
    test_param_used();
    test_fit_names();
    test_view_server();
    const char *frep = getenv("FREP"), *srcdir = getenv("srcdir");
    if (frep && srcdir) {
        test_same_as_command(frep, srcdir);
        test_segment(frep, srcdir);
        test_normals(frep, srcdir);
        test_segment_bare(frep);
        test_fit(frep);
        test_render(frep, srcdir);
        test_mesh_command(frep, srcdir);
        test_evolve(frep, srcdir);
        test_evolve_residual(frep);
        test_print_source(frep, srcdir);
        test_eval_grid(frep, srcdir);
        test_export_scad(frep, srcdir);
        test_view_page(frep, srcdir);
    }
    else diag("FREP or srcdir not set: the comparison with the command is skipped");
    char cmd[400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0) diag("could not remove %s", tmpdir);
    return done_testing();
}
