/* main.c - the frep command: dispatches `frep SUBCOMMAND ...` to cli/cmd_*.c.
 * The library (libfrep) never prints; everything users see is written from cli/.
 */
#include "config.h"

#include "cli.h"

#include <stdio.h>
#include <string.h>

typedef struct cli_command {
    const char *name;
    cli_cmd_fn fn;
    const char *summary;
} cli_command;

/* One entry per subcommand, in the order --help lists them. */
static const cli_command commands[] = {
    { "check", cmd_check, "parse and check a model file; report every problem" },
    { "eval", cmd_eval, "evaluate a model at points or on a grid (volume, throughput)" },
    { "print", cmd_print, "print the canonical source of a model file" },
    { "dis", cmd_dis, "print the bytecode of a compiled model" },
    { "mesh", cmd_mesh, "polygonize a model: STL, OBJ, PLY or OFF (dual contouring)" },
    { "sample", cmd_sample, "sample a point cloud with normals from a model or a mesh" },
    { "fit", cmd_fit, "fit a template's free parameters to a point cloud (SA + quasi-Newton)" },
    { "render", cmd_render, "draw a shaded PNG picture of a model, optionally with a cloud" },
    { "view", cmd_view, "write an HTML page that shows a model and a cloud in 3D (WebGL)" },
    { "normals", cmd_normals, "estimate the normals of a point cloud (robust, oriented outward)" },
    { "segment", cmd_segment, "find planes, spheres, cylinders, cones, tori in a point cloud" },
    { "evolve", cmd_evolve, "discover a construction-tree model (.hf) from a point cloud" },
    { "export", cmd_export, "translate a model into OpenSCAD source (.scad)" },
};

static void usage(FILE *f)
{
    fprintf(f, "usage: frep SUBCOMMAND [options] [args]\n\n"
               "frep %s: function-representation (FRep) modeling with HyperFun models.\n\n"
               "Subcommands:\n", FREP_VERSION_STRING);
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        fprintf(f, "  %-8s %s\n", commands[i].name, commands[i].summary);
    fprintf(f, "\n'frep SUBCOMMAND --help' describes a subcommand. frep --version prints the version.\n");
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        usage(stderr);
        return CLI_USAGE;
    }
    const char *sub = argv[1];
    if (strcmp(sub, "--help") == 0 || strcmp(sub, "-h") == 0 || strcmp(sub, "help") == 0) {
        usage(stdout);
        return CLI_OK;
    }
    if (strcmp(sub, "--version") == 0 || strcmp(sub, "version") == 0) {
        printf("frep %s\n", FREP_VERSION_STRING);
        return cli_stdout_close() == 0 ? CLI_OK : CLI_FAIL;
    }
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (strcmp(sub, commands[i].name) == 0) {
            cli_signals_install();
            int rc = commands[i].fn(argc - 1, argv + 1);
            /* output lost to a full disk or a closed pipe is a failure too */
            if (cli_stdout_close() != 0 && rc == CLI_OK) rc = CLI_FAIL;
            /* a signal that came after the last poll (during the write) still ends
             * the command with its status: an interrupted command never exits 0 */
            if (rc == CLI_OK && cli_interrupted())
                rc = cli_interrupt_status(sub, "after the output was complete");
            return rc;
        }
    fprintf(stderr, "frep: unknown subcommand '%s'\n", sub);
    usage(stderr);
    return CLI_USAGE;
}
