/* bench_api_eval.c - the C side of bench/bench_python.py: CPU time of frep_eval_par
 * (one thread) over N points of a model's box, median of RUNS runs.
 *   bench_api_eval MODEL.hf [N [RUNS]]   prints "c_eval_cpu_seconds MEDIAN"
 * The points are those bench_python.py makes: x, y, z evenly spaced over the box
 * diagonal, so both sides evaluate the same values.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "frep.h"

#define BENCH_MAX_RUNS 99

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv)
{
    if (argc < 2) return 2;
    size_t n = argc > 2 ? (size_t)atol(argv[2]) : 1000000;
    int runs = argc > 3 ? atoi(argv[3]) : 7;
    if (runs < 1 || runs > BENCH_MAX_RUNS || n == 0) return 2;
    static char text[1 << 20];
    FILE *f = fopen(argv[1], "rb");
    size_t len = f ? fread(text, 1, sizeof text, f) : 0;
    if (f) fclose(f);
    frep_program *p = frep_compile(argv[1], text, len, NULL, NULL, NULL);
    if (!p) return 1;
    double box[6] = { -1, -1, -1, 1, 1, 1 };
    frep_program_box(p, box);
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y), *z = malloc(n * sizeof *z),
           *v = malloc(n * sizeof *v);
    if (!x || !y || !z || !v) return 1;
    for (size_t i = 0; i < n; i++) {
        double t = n > 1 ? (double)i / (double)(n - 1) : 0;
        x[i] = box[0] + t * (box[3] - box[0]);
        y[i] = box[1] + t * (box[4] - box[1]);
        z[i] = box[2] + t * (box[5] - box[2]);
    }
    double secs[BENCH_MAX_RUNS];
    for (int r = 0; r < runs; r++) {
        clock_t t0 = clock();
        if (frep_eval_par(p, n, x, y, z, NULL, v, 1, NULL) != 0) return 1;
        secs[r] = (double)(clock() - t0) / CLOCKS_PER_SEC;
    }
    qsort(secs, (size_t)runs, sizeof *secs, cmp_double);
    double sum = 0;
    for (size_t i = 0; i < n; i++) sum += v[i];
    printf("c_eval_cpu_seconds %.6f checksum %.17g\n", secs[runs / 2], sum);
    free(x), free(y), free(z), free(v);
    frep_program_free(p);
    return 0;
}
