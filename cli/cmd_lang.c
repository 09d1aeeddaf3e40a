/* cmd_lang.c - the language subcommands: frep check, frep print, frep dis.
 * check and dis go through the public compiler; print re-prints the parsed tree
 * (lang/print.c), so it shows the file as frep understood it.
 */
#include "config.h"

#include "cli.h"

#include <getopt.h>
#include <stdlib.h>
#include <string.h>

#include "arena.h"
#include "ast.h"

static int help_or_file(int argc, char **argv, const char *usage, const char **file,
                        const char **model)
{
    static const struct option longopts[] = {
        { "help", no_argument, NULL, 'h' },
        { "model", required_argument, NULL, 'm' },
        { NULL, 0, NULL, 0 },
    };
    optind = 1;
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, "hm:", longopts, NULL)) != -1) {
        switch (c) {
        case 'h': fputs(usage, stdout); return CLI_OK;
        case 'm':
            if (!model) return cli_usage_error(argv[0], "--model is not an option here");
            *model = optarg;
            break;
        default:
            return cli_usage_error(argv[0], "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (argc - optind != 1) return cli_usage_error(argv[0], "expected one model file");
    *file = argv[optind];
    return -1;
}

int cmd_check(int argc, char **argv)
{
    const char *file = NULL;
    int r = help_or_file(argc, argv,
        "usage: frep check FILE.hf\n\n"
        "Parse and check every model of FILE.hf and report every problem found, as\n"
        "file:line:col: error: message, with the source line and a caret.\n"
        "Exit status: 0 when the file has no errors (warnings allowed), 1 otherwise.\n",
        &file, NULL);
    if (r >= 0) return r;
    size_t len;
    char *src = cli_read_file(file, &len);
    if (!src) return CLI_FAIL;
    cli_diag_ctx dc = { src, len, 0, 0, NULL, 0 };
    size_t nmodels = 0;
    char **models = frep_list_models(file, src, len, &nmodels, cli_print_diag, &dc);
    if (!models) {
        free(src);
        cli_diag_done(&dc);
        return CLI_FAIL;
    }
    frep_compile_options o;
    frep_compile_options_init(&o);
    int bad = 0;
    for (size_t i = 0; i < nmodels; i++) {
        o.model = models[i];
        frep_program *p = frep_compile(file, src, len, &o, cli_print_diag, &dc);
        if (!p) bad = 1;
        frep_program_free(p);
    }
    frep_free_strings(models, nmodels);
    free(src);
    cli_diag_done(&dc);
    return bad || dc.errors ? CLI_FAIL : CLI_OK;
}

int cmd_print(int argc, char **argv)
{
    const char *file = NULL;
    int r = help_or_file(argc, argv,
        "usage: frep print FILE.hf\n\n"
        "Print the canonical source of FILE.hf: the same program (parsing the output\n"
        "again gives the same tree), laid out uniformly, with annotations kept.\n",
        &file, NULL);
    if (r >= 0) return r;
    size_t len;
    char *src = cli_read_file(file, &len);
    if (!src) return CLI_FAIL;
    cli_diag_ctx dc = { src, len, 0, 0, NULL, 0 };
    diag_sink ds = { cli_print_diag, &dc, file, 0, 0 };
    arena A;
    arena_init(&A);
    ast_file f;
    int status = CLI_FAIL;
    if (ast_parse(&A, file, src, len, &ds, &f) == 0) {
        char *out = ast_print(&f);
        if (out) {
            fputs(out, stdout);
            free(out);
            status = CLI_OK;
        }
    }
    arena_free(&A);
    free(src);
    cli_diag_done(&dc);
    return status;
}

int cmd_dis(int argc, char **argv)
{
    const char *file = NULL, *model = NULL;
    int r = help_or_file(argc, argv,
        "usage: frep dis [--model NAME] FILE.hf\n\n"
        "Compile a model of FILE.hf and print its bytecode: one instruction a line\n"
        "with its operands and source position (see doc/architecture.md).\n"
        "Without --model: my_model if present, else the last model of the file.\n",
        &file, &model);
    if (r >= 0) return r;
    frep_program *p = cli_compile_file(file, model, NULL, 0, -1, NULL);
    if (!p) return CLI_FAIL;
    char *s = frep_disassemble(p);
    frep_program_free(p);
    if (!s) return CLI_FAIL;
    fputs(s, stdout);
    free(s);
    return CLI_OK;
}
