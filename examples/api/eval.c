/* eval.c - libfrep from a C program: compile a model, evaluate it at a few points,
 * polygonize it and write the mesh.
 *
 *   cc eval.c $(pkg-config --cflags --libs frep) -o eval
 *   ./eval MODEL.hf OUT.stl [GRID]
 */
#include <frep.h>

#include <stdio.h>
#include <stdlib.h>

/* The library never prints: diagnostics come here. */
static void print_diag(void *user, const frep_diag *d)
{
    char *s = frep_diag_format(d, NULL, 0);
    fputs(s ? s : d->message, stderr);
    frep_free(s);
    (void)user;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: %s MODEL.hf OUT.stl [GRID]\n", argv[0]);
        return 2;
    }
    FILE *f = fopen(argv[1], "rb");
    static char text[1 << 20];
    size_t len = f ? fread(text, 1, sizeof text, f) : 0;
    if (f) fclose(f);
    frep_program *p = frep_compile(argv[1], text, len, NULL, print_diag, NULL);
    if (!p) return 1;
    printf("libfrep %s (header %s), %zu instructions, %zu parameters\n", frep_version(),
           FREP_VERSION_STRING, frep_program_size(p), frep_program_nparams(p));

    /* values at three points, with the program's own parameters */
    double x[3] = { 0, 0.5, 2 }, y[3] = { 0, 0, 0 }, z[3] = { 0, 0, 0 }, v[3];
    if (frep_eval_par(p, 3, x, y, z, NULL, v, 0, NULL) != 0) return 1;
    for (int i = 0; i < 3; i++) printf("f(%g, %g, %g) = %.9g\n", x[i], y[i], z[i], v[i]);

    /* the mesh of the model's box at the grid asked, written as frep mesh does */
    frep_mesh_options o;
    frep_mesh_options_init(&o);
    if (argc > 3) o.grid = atoi(argv[3]);
    frep_mesh *m = frep_polygonize(p, &o, NULL, print_diag, NULL);
    int rc = m && frep_mesh_write(m, argv[2], FREP_MESH_AUTO, 0, print_diag, NULL) == 0 ? 0 : 1;
    if (m) printf("%s: %zu vertices, %zu triangles\n", argv[2], frep_mesh_nverts(m),
                  frep_mesh_ntris(m));
    frep_mesh_free(m);
    frep_program_free(p);
    return rc;
}
