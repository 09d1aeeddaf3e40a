/* cmd_view.c - frep view: the page of a model (polygonized as by frep mesh, through
 * cli/model.c, or a mesh file) and of a cloud with its distances
 * (frep_cloud_distances), written by frep_view_write_page() as one self-contained HTML
 * file with a WebGL viewer; with --watch served on 127.0.0.1 (frep_view_server) and
 * rebuilt on every save.  On the public API only.
 */
#include "config.h"

#include "cli.h"

#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

/* Colour scale when no distance is finite and positive (a cloud exactly on the
 * surface): any positive value draws every point blue. */
#define VIEW_FALLBACK_SCALE 1.0

static const char view_usage[] =
    "usage: frep view FILE.hf [--points CLOUD] [-o VIEW.html] [options]\n"
    "       frep view MESH.(off|obj|stl|ply) [--points CLOUD] [-o VIEW.html]\n\n"
    "Write one self-contained HTML page (it opens from disk: no server, no network) that\n"
    "draws the model, polygonized as by frep mesh, in WebGL: orbit (left drag), pan\n"
    "(right or shift drag), zoom (wheel), standard views, a section plane, wireframe.\n"
    "With --points the cloud is drawn too, each point coloured by its distance\n"
    "|f|/|grad f| to the surface, points inside the solid drawn through it as rings,\n"
    "and the surface can be coloured by its distance to the nearest point (material the\n"
    "cloud does not show). The model's text and parameters are beside the picture.\n\n"
    "With --watch the page is served on http://127.0.0.1:PORT/ instead, and the model\n"
    "is meshed again on every save of it (or of the cloud); the open page follows, and\n"
    "shows compile errors with their file:line:col. Ctrl-C stops the server.\n\n";

/* --watch: how often the files are checked for a save, in milliseconds (the page asks
 * for a new version every 200 ms; a save shows within about 0.3 s plus meshing). */
#define VIEW_WATCH_POLL_MS 100
/* A save is acted on once the files' stamps stay the same this long: a cloud or model
 * still being written (truncated, then filled) is not read half-way. */
#define VIEW_WATCH_SETTLE_MS 100
#define VIEW_WATCH_SETTLE_MAX 50   /* at most this many settle steps (5 s), then rebuild */
#define VIEW_DEFAULT_PORT "8018"
/* Grid of the page of frep fit --view and frep evolve --view: frep view's default. */
#define VIEW_DEFAULT_GRID 128

/* What one build of the page holds: the mesh, the cloud and their distances, the
 * parameters of the program the mesh was made of. */
typedef struct view_build {
    frep_mesh *m;            /* NULL until a build succeeds */
    frep_mesh_info mi;       /* what the mesher did (a model's build) */
    cli_cloud_dist cd;       /* --points and its distances */
    uint8_t *vrgb;           /* the model's colours at the vertices, else NULL */
    size_t np;
    char **pnames;
    double *pvalues;
    char info[160];
} view_build;

typedef struct view_cmd {
    mesh_cli mc;
    const char *in, *out, *points;
    double scale;            /* --scale: 0 chooses it from the data */
    int quiet, watch, port;
    FILE *summary;           /* where the summary line goes (NULL: stdout) */
    double timeout;          /* --watch: stop after this many seconds (0: at Ctrl-C) */
    view_build b;            /* the last good build */
    char *text;              /* --watch: the model's text as last read */
    cli_text diag;           /* messages of the last build of the mesh */
    cli_text cdiag;          /* --watch: messages of the last reading of the cloud */
    int failed;              /* --watch: the last build failed (its mesh is an older one) */
    unsigned version;
    char vtext[16];          /* --watch: the version as the server sends it */
    char *page, *json;       /* --watch: what the server sends */
    size_t page_len, json_len;
    char stamp[2][64];       /* --watch: mtime and size of the model and the cloud */
} view_cmd;

#define OFF(f) offsetof(view_cmd, f)
static const cli_opt view_opts[] = {
    { 'o', "output", "HTML", CLI_OPT_STRING, OFF(out), .def = "view.html",
      .help = "the page to write (default view.html)" },
    { 0, "points", "CLOUD", CLI_OPT_STRING, OFF(points), .help = "a point cloud (.xyz or .ply)" },
    { 'w', "watch", NULL, CLI_OPT_SET, OFF(watch),
      .help = "serve the page on 127.0.0.1 and rebuild it on every save" },
    { 0, "port", "N", CLI_OPT_INT, OFF(port), .lo = 0, .hi = 65535, .def = VIEW_DEFAULT_PORT,
      .help = "the port of the watch server (default " VIEW_DEFAULT_PORT "; 0: any free)" },
    { 0, "timeout", "S", CLI_OPT_DOUBLE, OFF(timeout), .lo = 0, .hi = INFINITY,
      .what = "seconds", .help = "stop the watch server after S seconds (default 0: at Ctrl-C)" },
    { 0, "scale", "D", CLI_OPT_DOUBLE, OFF(scale), .lo = 0, .hi = INFINITY, .open_lo = 1,
      .what = "a distance", .help = "point distance drawn red (default: from the data, the\n"
                                    "95th percentile rounded up to 1, 2 or 5 x 10^k)" },
    CLI_OPT_MODEL(view_cmd, mc.model, "the model (default: my_model, else the first one)"),
    CLI_OPT_PARAMS(view_cmd, mc.a, "values of the model's a[] array"),
    CLI_OPT_BOX(view_cmd, mc.box, "HyperFun's -b (default: the model's '-- @box', else 10)"),
    CLI_OPT_GRID(view_cmd, mc.grid, "128", "grid cells per axis of the mesh (default 128)"),
    CLI_OPT_ISO(view_cmd, mc.iso, "draw f = V"),
    CLI_OPT_SETOPS(view_cmd, mc.setops, "override the file's set operations: rfunc, minmax"),
    CLI_OPT_STRICT(view_cmd, mc.strict),
    CLI_OPT_THREADS(view_cmd, mc.nthreads, "OpenMP threads"),
    CLI_OPT_QUIET(view_cmd, quiet, "no summary line"),
};
#undef OFF
static const cli_opt_spec view_spec = { "view", view_usage, view_opts,
                                        sizeof view_opts / sizeof view_opts[0], 22 };

/* The model's mesh: a mesh file as it is, or the model compiled and polygonized. */
static int stage_mesh(view_cmd *c, view_build *b)
{
    if (cli_is_mesh_path(c->in)) return (b->m = cli_mesh_read(c->in)) ? CLI_OK : CLI_FAIL;
    if (mesh_cli_compile(&c->mc, c->in) != CLI_OK) return CLI_FAIL;
    if (mesh_cli_mesh(&c->mc, "view", &b->m, &b->mi) != CLI_OK) return CLI_FAIL;
    snprintf(b->info, sizeof b->info, "grid %d, box [%g,%g]x[%g,%g]x[%g,%g], meshed in %.2f s",
             c->mc.grid, c->mc.box[0], c->mc.box[3], c->mc.box[1], c->mc.box[4], c->mc.box[2],
             c->mc.box[5], b->mi.seconds);
    return CLI_OK;
}

/* The free parameters of the model, for the side panel (copied: the program is
 * replaced by the next build). */
static int stage_params(view_cmd *c, view_build *b)
{
    if (!c->mc.p) return CLI_OK;
    b->np = frep_program_nparams(c->mc.p);
    b->pnames = calloc(b->np + 1, sizeof *b->pnames);
    b->pvalues = calloc(b->np + 1, sizeof *b->pvalues);
    int ok = b->pnames && b->pvalues;
    for (size_t i = 0; ok && i < b->np; i++) {
        b->pnames[i] = strdup(frep_program_param_name(c->mc.p, i));
        b->pvalues[i] = frep_program_param_value(c->mc.p, i);
        ok = b->pnames[i] != NULL;
    }
    if (ok) return CLI_OK;
    fprintf(stderr, "frep view: out of memory\n");
    return CLI_FAIL;
}

/* The model's colours, s[1..3] at the vertices (cli/model.c), when it has them. */
static int stage_colors(view_cmd *c, view_build *b)
{
    if (!c->mc.p) return CLI_OK;
    return mesh_cli_vertex_colors(&c->mc, "view", b->m, &b->vrgb);
}

/* The colour scales: from the data, VIEW_FALLBACK_SCALE when the data gives none,
 * --scale for the points when given. */
static void set_scales(const view_cmd *c, frep_distances *d)
{
    if (!(d->point_scale > 0)) d->point_scale = VIEW_FALLBACK_SCALE;
    if (!(d->vertex_scale > 0)) d->vertex_scale = VIEW_FALLBACK_SCALE;
    if (c->scale > 0) d->point_scale = c->scale;
}

/* Triangles of the build's mesh (0 before the first good build). */
static size_t build_ntris(const view_build *b)
{
    return b->m ? frep_mesh_ntris(b->m) : 0;
}

/* --points: the cloud (read, or b->cd.cl as it is: --watch keeps a cloud that was not
 * saved again) and its distances (cli/model.c); --scale. */
static int stage_points(view_cmd *c, view_build *b)
{
    int rc = b->cd.cl ? cli_cloud_measure("view", &c->mc, b->m, &b->cd)
                      : cli_cloud_distances("view", c->points, &c->mc, b->m, &b->cd);
    if (rc != CLI_OK) return CLI_FAIL;
    set_scales(c, &b->cd.d);
    return CLI_OK;
}

static void build_free(view_build *b)
{
    frep_mesh_free(b->m);
    cli_cloud_dist_free(&b->cd);
    frep_free(b->vrgb);
    for (size_t i = 0; b->pnames && i < b->np; i++) free(b->pnames[i]);
    free(b->pnames);
    free(b->pvalues);
    memset(b, 0, sizeof *b);
}

/* mesh -> parameters -> colours -> [points]: a new build into *b (released on
 * failure).  cloud: a cloud already read, used instead of reading --points (it stays
 * the caller's when the build fails), or NULL. */
static int build(view_cmd *c, view_build *b, frep_cloud *cloud)
{
    memset(b, 0, sizeof *b);
    int rc = stage_mesh(c, b);
    if (rc == CLI_OK) rc = stage_params(c, b);
    if (rc == CLI_OK) rc = stage_colors(c, b);
    b->cd.cl = cloud;
    if (rc == CLI_OK && c->points) rc = stage_points(c, b);
    if (rc != CLI_OK) {
        if (b->cd.cl == cloud) b->cd.cl = NULL;
        build_free(b);
    }
    return rc;
}

/* The scene of the page: the last good build, the current text and messages. */
static void make_scene(const view_cmd *c, frep_view_scene *s)
{
    const view_build *b = &c->b;
    frep_view_scene_init(s);
    s->name = c->in;
    s->mesh = b->m;
    s->source = c->text ? c->text : c->mc.src;
    s->nparams = b->np;
    s->pnames = (const char *const *)b->pnames;
    s->pvalues = b->pvalues;
    s->info = b->info;
    s->diag = c->diag.len ? c->diag.s : NULL;
    s->cdiag = c->cdiag.len ? c->cdiag.s : NULL;
    s->failed = c->failed;
    s->vrgb = b->vrgb;
    s->version = c->version;
    if (b->cd.cl) {
        s->npoints = frep_cloud_size(b->cd.cl);
        frep_cloud_arrays(b->cd.cl, &s->px, &s->py, &s->pz, NULL, NULL, NULL);
        s->pdist = b->cd.d.point;
        s->pscale = b->cd.d.point_scale;
        s->vdist = b->cd.d.vertex;
        s->vscale = b->cd.d.vertex_scale;
    }
}

/* The library's messages without a position, as "frep view: ...". */
static void view_diag(void *user, const frep_diag *d)
{
    (void)user;
    cli_library_diag("view", d);
}

static int write_page_cb(FILE *f, void *user)
{
    const view_cmd *c = user;
    frep_view_scene s;
    make_scene(c, &s);
    return frep_view_write_page(&s, f, view_diag, NULL);
}

/* The summary line: the page, its size, what it holds. */
static void report(const view_cmd *c)
{
    FILE *f = fopen(c->out, "rb");
    long size = -1;
    if (f && fseek(f, 0, SEEK_END) == 0) size = ftell(f);
    if (f) fclose(f);
    FILE *o = c->summary ? c->summary : stdout;
    fprintf(o, "%s: %.2f MB, %zu triangles", c->out, (double)size / 1e6, build_ntris(&c->b));
    if (c->b.cd.cl)
        fprintf(o, ", %zu points (colour scale %g)", frep_cloud_size(c->b.cd.cl),
                c->b.cd.d.point_scale);
    fprintf(o, "\n");
}

/* build -> write -> report */
static int view_once(view_cmd *c)
{
    c->mc.diag = &c->diag;
    int rc = build(c, &c->b, NULL);
    if (rc != CLI_OK) return rc;
    if (cli_write_atomic(c->out, write_page_cb, c) != 0) return CLI_FAIL;
    if (!c->quiet) report(c);
    return CLI_OK;
}

/* The model text a writer callback makes, in memory (free()); NULL when it fails. */
static char *model_text(const cli_view_job *j)
{
    char *text = NULL;
    size_t len = 0;
    FILE *m = open_memstream(&text, &len);
    if (!m) return NULL;
    int rc = j->write_model(m, j->user);
    if (fclose(m) != 0 || rc != 0) {
        free(text);
        return NULL;
    }
    return text;
}

int cli_view_result(const cli_view_job *j)
{
    view_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    c.mc.grid = VIEW_DEFAULT_GRID;
    c.mc.nthreads = j->nthreads;
    c.mc.model = j->model;
    c.in = j->name ? j->name : "(standard output)";
    c.summary = j->name ? stdout : stderr;
    c.out = j->out;
    c.points = j->cloud;
    c.quiet = j->quiet;
    char *text = model_text(j);
    c.mc.text = text;
    if (j->a && j->na) {
        c.mc.a.v = malloc(j->na * sizeof *c.mc.a.v);
        if (c.mc.a.v) memcpy(c.mc.a.v, j->a, j->na * sizeof *c.mc.a.v);
        c.mc.a.n = c.mc.a.v ? j->na : 0;
    }
    int rc = text ? view_once(&c) : CLI_FAIL;
    if (!text) fprintf(stderr, "frep %s: cannot write the model for --view\n", j->sub);
    build_free(&c.b);
    cli_text_free(&c.diag);
    mesh_cli_free(&c.mc);
    free(text);
    return rc;
}

/* ---- --watch ---------------------------------------------------------------- */

/* "mtime size" of a file ("" when it cannot be read): a save changes it. */
static void file_stamp(const char *path, char out[64])
{
    struct stat st;
    out[0] = '\0';
    if (path && stat(path, &st) == 0)
        snprintf(out, 64, "%lld.%09ld %lld", (long long)st.st_mtim.tv_sec,
                 (long)st.st_mtim.tv_nsec, (long long)st.st_size);
}

/* The page and the scene JSON the server sends, for the current version. */
static int render_replies(view_cmd *c)
{
    frep_view_scene s;
    make_scene(c, &s);
    frep_free(c->page);
    frep_free(c->json);
    c->page = frep_view_page(&s, 1, &c->page_len, NULL, NULL);
    snprintf(c->vtext, sizeof c->vtext, "%u", c->version);
    c->json = frep_view_scene_json(&s, &c->json_len, NULL, NULL);
    if (c->page && c->json) return CLI_OK;
    fprintf(stderr, "frep view: out of memory\n");
    return CLI_FAIL;
}

/* A new build of the mesh after a save of the model (and the first): read the text,
 * build with the cloud as it is unless it was saved too; on failure keep the last good
 * build and show the messages in the page.  Returns what was done, for the log. */
static const char *rebuild_model(view_cmd *c, int cloud_saved)
{
    cli_text_free(&c->diag);
    if (cloud_saved) {
        cli_text_free(&c->cdiag);
    }
    free(c->text);
    c->text = cli_is_mesh_path(c->in) ? NULL : cli_read_file(c->in, NULL);
    frep_program *old_p = c->mc.p;
    char *old_src = c->mc.src;
    c->mc.p = NULL;
    c->mc.src = NULL;
    view_build nb;
    frep_cloud *keep = cloud_saved ? NULL : c->b.cd.cl;
    c->mc.diag = &c->diag;
    if (build(c, &nb, keep) == CLI_OK) {
        if (keep) c->b.cd.cl = NULL;  /* now nb's */
        build_free(&c->b);
        c->b = nb;
        if (old_p) frep_program_free(old_p);
        free(old_src);
        c->failed = 0;
        return keep ? "model meshed again, cloud kept" : "model meshed, cloud read";
    }
    if (c->mc.p) frep_program_free(c->mc.p);
    free(c->mc.src);
    c->mc.p = old_p;
    c->mc.src = old_src;
    c->failed = 1;
    if (!c->diag.len)
        cli_text_printf(&c->diag, "%s: no new mesh (the messages are in the terminal)\n", c->in);
    return "the model failed, last good mesh kept";
}

/* After a save of the cloud alone: read it, measure it against the mesh as it is. */
static const char *rebuild_cloud(view_cmd *c)
{
    cli_text_free(&c->cdiag);
    c->mc.diag = &c->cdiag;
    cli_cloud_dist cd;
    int rc = cli_cloud_distances("view", c->points, &c->mc, c->b.m, &cd);
    c->mc.diag = &c->diag;
    if (rc != CLI_OK) {
        cli_cloud_dist_free(&cd);
        return "the cloud failed, last good cloud kept";
    }
    cli_cloud_dist_free(&c->b.cd);
    c->b.cd = cd;
    set_scales(c, &c->b.cd.d);
    return "cloud read again, mesh kept";
}

/* A new version after a save: only what depends on the files saved is done again (a
 * save of the cloud measures the new cloud against the mesh as it is; a save of the
 * model meshes it again and measures the cloud as it is).  The first version does
 * everything. */
static int rebuild(view_cmd *c)
{
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    char now[2][64];
    file_stamp(c->in, now[0]);
    file_stamp(c->points, now[1]);
    int first = c->version == 0;
    int model_saved = first || strcmp(now[0], c->stamp[0]) != 0;
    int cloud_saved = first || strcmp(now[1], c->stamp[1]) != 0;
    memcpy(c->stamp, now, sizeof now);
    const char *what;
    if (model_saved || c->failed || !c->b.cd.cl) what = rebuild_model(c, cloud_saved);
    else what = rebuild_cloud(c);
    c->version++;
    int rc = render_replies(c);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (!c->quiet)
        fprintf(stderr, "frep view: version %u of %s: %s (%zu triangles%s), %.2f s\n", c->version,
                c->in, what, build_ntris(&c->b), c->failed ? ", with errors" : "",
                (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec));
    return rc;
}

/* The server's routes: the page, its version, the scene. */
static void route(void *user, const char *path, frep_view_reply *r)
{
    view_cmd *c = user;
    static const char json_type[] = "application/json";
    if (strcmp(path, "/") == 0 || strncmp(path, "/?", 2) == 0 || strcmp(path, "/index.html") == 0) {
        *r = (frep_view_reply){ 200, "text/html; charset=utf-8", c->page, c->page_len };
    } else if (strcmp(path, "/version") == 0) {
        *r = (frep_view_reply){ 200, "text/plain", c->vtext, strlen(c->vtext) };
    } else if (strcmp(path, "/scene.json") == 0) {
        *r = (frep_view_reply){ 200, json_type, c->json, c->json_len };
    }
}

/* Has the model or the cloud been saved since the last build? */
static int changed(const view_cmd *c)
{
    char now[2][64];
    file_stamp(c->in, now[0]);
    file_stamp(c->points, now[1]);
    return strcmp(now[0], c->stamp[0]) != 0 || strcmp(now[1], c->stamp[1]) != 0;
}

/* Wait, serving, until the stamps of the model and the cloud have stayed the same for
 * VIEW_WATCH_SETTLE_MS (at most VIEW_WATCH_SETTLE_MAX such waits). */
static void settle(view_cmd *c, frep_view_server *srv)
{
    char before[2][64], after[2][64];
    file_stamp(c->in, before[0]);
    file_stamp(c->points, before[1]);
    struct timespec since, t;
    clock_gettime(CLOCK_MONOTONIC, &since);
    for (int i = 0; i < VIEW_WATCH_SETTLE_MAX * 10 && !cli_interrupted(); i++) {
        frep_view_server_step(srv, VIEW_WATCH_SETTLE_MS / 10, route, c);
        file_stamp(c->in, after[0]);
        file_stamp(c->points, after[1]);
        clock_gettime(CLOCK_MONOTONIC, &t);
        if (strcmp(before[0], after[0]) != 0 || strcmp(before[1], after[1]) != 0) {
            memcpy(before, after, sizeof before);
            since = t;
        } else if ((double)(t.tv_sec - since.tv_sec) * 1e3 +
                       1e-6 * (double)(t.tv_nsec - since.tv_nsec) >= VIEW_WATCH_SETTLE_MS) {
            return;
        }
    }
}

/* Serve until Ctrl-C or --timeout, rebuilding after every save. */
static int view_watch(view_cmd *c)
{
    if (rebuild(c) != CLI_OK) return CLI_FAIL;
    frep_view_server *srv = frep_view_server_open(c->port, view_diag, NULL);
    if (!srv) return CLI_FAIL;
    printf("frep view: serving %s on http://127.0.0.1:%d/ (Ctrl-C stops)\n", c->in,
           frep_view_server_port(srv));
    fflush(stdout);
    cli_sigint_catch();
    struct timespec t0, t;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int rc = CLI_OK;
    while (rc == CLI_OK && !cli_interrupted()) {
        frep_view_server_step(srv, VIEW_WATCH_POLL_MS, route, c);
        clock_gettime(CLOCK_MONOTONIC, &t);
        if (c->timeout > 0 && (double)(t.tv_sec - t0.tv_sec) + 1e-9 * (double)(t.tv_nsec - t0.tv_nsec) >= c->timeout)
            break;
        if (changed(c)) {
            settle(c, srv);
            rc = rebuild(c);
        }
    }
    cli_sigint_restore();
    cli_interrupt_handled();  /* Ctrl-C is how a watch ends */
    frep_view_server_close(srv);
    if (!c->quiet) fprintf(stderr, "frep view: stopped\n");
    return rc;
}

/* Options -> one model or mesh file. */
static int stage_options(view_cmd *c, int argc, char **argv)
{
    cli_args args;
    int rc = mesh_cli_parse(&view_spec, argc, argv, c, offsetof(view_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("view", "expected one input: FILE.hf or a mesh file");
    c->in = args.v[0];
    return CLI_GO_ON;
}

int cmd_view(int argc, char **argv)
{
    view_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    int rc = stage_options(&c, argc, argv);
    if (rc == CLI_GO_ON) rc = c.watch ? view_watch(&c) : view_once(&c);
    build_free(&c.b);
    free(c.text);
    cli_text_free(&c.diag);
    cli_text_free(&c.cdiag);
    frep_free(c.page);
    frep_free(c.json);
    mesh_cli_free(&c.mc);
    return rc;
}
