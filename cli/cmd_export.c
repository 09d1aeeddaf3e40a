/* cmd_export.c - frep export: a model as OpenSCAD source (frep_export_scad), written
 * atomically.  The model is compiled first, as frep mesh compiles it, so its errors
 * read the same and the box is the one frep mesh would use.
 */
#include "config.h"

#include "cli.h"

#include <stdlib.h>
#include <string.h>

static const char export_usage[] =
    "usage: frep export FILE.hf -o OUT.scad [options]\n\n"
    "Translate a model into OpenSCAD source: the same solid as constructive solid\n"
    "geometry of spheres, ellipsoids, blocks and boxes, cylinders, cones and tori, moved,\n"
    "turned and scaled, under union(), intersection() and difference(); each\n"
    "sub-expression the model names becomes a module of that name. The translation runs\n"
    "the model's compiled tree, so any straight-line model of such solids and set\n"
    "operations (of any family: R-functions have the sign of min/max) translates; a\n"
    "construct with no OpenSCAD equivalent (a blend, x[1]^2, an if that depends on the\n"
    "point) is an error at its position. Half-spaces and infinite cylinders become\n"
    "solids 4 box diagonals long around the box; an unbounded model is cut by the box.\n\n";

typedef struct export_cmd {
    mesh_cli mc;
    const char *out;
    int fn, quiet;
    char *text;
    size_t len;
} export_cmd;

#define OFF(f) offsetof(export_cmd, f)
static const cli_opt export_opts[] = {
    { 'o', "output", "OUT", CLI_OPT_STRING, OFF(out), .help = "the .scad file to write (required; '-': stdout)" },
    CLI_OPT_MODEL(export_cmd, mc.model, "the model to export (default: my_model, else the last one)"),
    CLI_OPT_PARAMS(export_cmd, mc.a, "values of the model's a[] array, comma separated"),
    CLI_OPT_BOX(export_cmd, mc.box,
                "the box of an unbounded model, as frep mesh's -b; default:\n"
                "the model's '-- @box' annotation, else 10"),
    { 0, "fn", "N", CLI_OPT_INT, OFF(fn), .lo = 3, .hi = FREP_SCAD_MAX_FN, .what = "facets",
      .def = "48", .help = "OpenSCAD's $fn, facets of a full circle (default 48)" },
    CLI_OPT_QUIET(export_cmd, quiet, "no summary line"),
};
#undef OFF
static const cli_opt_spec export_spec = { "export", export_usage, export_opts,
                                          sizeof export_opts / sizeof export_opts[0], 22 };

/* The export's messages: those with a position as the compiler's (with the source
 * line), the one without (the export failed) kept for "frep export: ...". */
typedef struct export_diag {
    cli_diag_ctx dc;
    char error[512];
} export_diag;

static void export_diag_cb(void *user, const frep_diag *d)
{
    export_diag *x = user;
    if (d->file) cli_print_diag(&x->dc, d);
    else if (!x->error[0]) snprintf(x->error, sizeof x->error, "%s", d->message);
}

static int write_text(FILE *f, void *user)
{
    const export_cmd *c = user;
    return fwrite(c->text, 1, c->len, f) == c->len ? 0 : -1;
}

int cmd_export(int argc, char **argv)
{
    export_cmd c;
    memset(&c, 0, sizeof c);
    mesh_cli_init(&c.mc);
    c.fn = FREP_SCAD_DEFAULT_FN;
    cli_args args;
    int rc = mesh_cli_parse(&export_spec, argc, argv, &c, offsetof(export_cmd, mc), &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error("export", "expected one model file FILE.hf");
    if (!c.out) return cli_usage_error("export", "-o OUT.scad is required");
    const char *path = args.v[0];
    if (mesh_cli_compile(&c.mc, path) != CLI_OK) {
        mesh_cli_free(&c.mc);
        return CLI_FAIL;
    }
    frep_scad_options o;
    frep_scad_options_init(&o);
    o.model = c.mc.model;
    o.a = c.mc.a.v;
    o.na = c.mc.a.n;
    memcpy(o.box, c.mc.box, sizeof o.box);
    o.fn = c.fn;
    export_diag xd = { { c.mc.src, c.mc.srclen, 0, 0, NULL, 0, NULL }, "" };
    c.text = frep_export_scad(path, c.mc.src, c.mc.srclen, &o, export_diag_cb, &xd);
    cli_diag_done(&xd.dc);
    int status = CLI_FAIL;
    if (!c.text) {
        fprintf(stderr, "frep export: %s\n", xd.error[0] ? xd.error : "out of memory");
    } else {
        c.len = strlen(c.text);
        if (strcmp(c.out, "-") == 0) {
            status = fwrite(c.text, 1, c.len, stdout) == c.len ? CLI_OK : CLI_FAIL;
        } else if (cli_write_atomic(c.out, write_text, &c) == 0) {
            status = CLI_OK;
            if (!c.quiet) printf("frep export: %s -> %s\n", path, c.out);
        }
    }
    frep_free(c.text);
    mesh_cli_free(&c.mc);
    return status;
}
