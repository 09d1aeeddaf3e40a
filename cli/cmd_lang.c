/* cmd_lang.c - the language subcommands: frep check, frep print, frep dis, on the
 * public API alone: check and dis through the compiler, print through
 * frep_print_source (the parsed tree re-printed, so it shows the file as frep
 * understood it).
 */
#include "config.h"

#include "cli.h"

#include <stdlib.h>
#include <string.h>

/* The input of every language subcommand: one model file (and for dis a model name). */
typedef struct lang_cmd {
    const char *model;
    const char *file;
    char *src;               /* the file's text (free()) */
    size_t len;
    int strict;              /* --strict: HyperFun's rejections are errors */
} lang_cmd;

static const cli_opt dis_opts[] = {
    CLI_OPT_MODEL(lang_cmd, model, NULL),
    CLI_OPT_STRICT(lang_cmd, strict),
};

/* Options -> the one model file, read. Returns CLI_GO_ON or an exit status. */
static int lang_input(const cli_opt_spec *spec, int argc, char **argv, lang_cmd *c, int read)
{
    cli_args args;
    int rc = cli_opt_parse(spec, argc, argv, c, &args);
    if (rc != CLI_GO_ON) return rc;
    if (args.n != 1) return cli_usage_error(spec->sub, "expected one model file");
    c->file = args.v[0];
    if (read && !(c->src = cli_read_file(c->file, &c->len))) return CLI_FAIL;
    return CLI_GO_ON;
}

static const cli_opt check_opts[] = {
    CLI_OPT_STRICT(lang_cmd, strict),
};

static const cli_opt_spec check_spec = { "check",
    "usage: frep check [--strict] FILE.hf\n\n"
    "Parse and check every model of FILE.hf and report every problem found, as\n"
    "file:line:col: error: message, with the source line and a caret.\n"
    "Exit status: 0 when the file has no errors (warnings allowed), 1 otherwise.\n",
    check_opts, sizeof check_opts / sizeof check_opts[0], 0 };

/* Compile every model of the file: each reports its own problems. */
static int check_models(const lang_cmd *c, cli_diag_ctx *dc)
{
    size_t nmodels = 0;
    char **models = frep_list_models(c->file, c->src, c->len, &nmodels, cli_print_diag, dc);
    if (!models) return CLI_FAIL;
    frep_compile_options o;
    frep_compile_options_init(&o);
    o.strict = c->strict;
    int bad = 0;
    for (size_t i = 0; i < nmodels; i++) {
        o.model = models[i];
        frep_program *p = frep_compile(c->file, c->src, c->len, &o, cli_print_diag, dc);
        if (!p) bad = 1;
        frep_program_free(p);
    }
    frep_free_strings(models, nmodels);
    return bad || dc->errors ? CLI_FAIL : CLI_OK;
}

int cmd_check(int argc, char **argv)
{
    lang_cmd c = { 0 };
    int rc = lang_input(&check_spec, argc, argv, &c, 1);
    if (rc != CLI_GO_ON) return rc;
    cli_diag_ctx dc = { c.src, c.len, 0, 0, NULL, 0, NULL };
    rc = check_models(&c, &dc);
    cli_diag_done(&dc);
    free(c.src);
    return rc;
}

static const cli_opt print_opts[] = {
    CLI_OPT_STRICT(lang_cmd, strict),
};

static const cli_opt_spec print_spec = { "print",
    "usage: frep print [--strict] FILE.hf\n\n"
    "Print the canonical source of FILE.hf: the same program (parsing the output\n"
    "again gives the same tree), laid out uniformly, with annotations kept.\n"
    "--strict: check the file as frep check --strict does first, print nothing\n"
    "if it has errors.\n",
    print_opts, sizeof print_opts / sizeof print_opts[0], 0 };

int cmd_print(int argc, char **argv)
{
    lang_cmd c = { 0 };
    int rc = lang_input(&print_spec, argc, argv, &c, 1);
    if (rc != CLI_GO_ON) return rc;
    cli_diag_ctx dc = { c.src, c.len, 0, 0, NULL, 0, NULL };
    int status = CLI_FAIL;
    char *out = frep_print_source(c.file, c.src, c.len, c.strict, NULL, cli_print_diag, &dc);
    if (out) {
        fputs(out, stdout);
        frep_free(out);
        status = CLI_OK;
    }
    free(c.src);
    cli_diag_done(&dc);
    return status;
}

static const cli_opt_spec dis_spec = { "dis",
    "usage: frep dis [--model NAME] [--strict] FILE.hf\n\n"
    "Compile a model of FILE.hf and print its bytecode: one instruction a line\n"
    "with its operands and source position (see doc/architecture.md).\n"
    "Without --model: my_model if present, else the first model of the file.\n",
    dis_opts, sizeof dis_opts / sizeof dis_opts[0], 0 };

int cmd_dis(int argc, char **argv)
{
    lang_cmd c = { 0 };
    int rc = lang_input(&dis_spec, argc, argv, &c, 0);
    if (rc != CLI_GO_ON) return rc;
    frep_program *p = cli_compile_file(c.file, c.model, NULL, 0, -1, c.strict, NULL);
    if (!p) return CLI_FAIL;
    char *s = frep_disassemble(p);
    frep_program_free(p);
    if (!s) return CLI_FAIL;
    fputs(s, stdout);
    frep_free(s);
    return CLI_OK;
}
