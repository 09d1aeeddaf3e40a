/* fuzz_readers.c - libFuzzer targets for every data reader of frep: point clouds (.xyz
 * text and PLY), triangle meshes (OFF, STL, OBJ, PLY), the .fit primitive list and the
 * .hf primitive list of frep segment / evolve -p.  One source, one target per build:
 * FUZZ_READER selects the reader (tests/fuzz.sh builds each with clang, ASan and
 * UBSan, and runs it on its seed corpus tests/fuzz/NAME/).  What a reader accepts is
 * also checked: every coordinate finite, every index in range, every primitive a
 * surface (prim_degenerate).  Not part of make check; crashers become regression tests.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "alloc.h"
#include "cloud.h"
#include "meshio.h"
#include "prim.h"
#include "segment.h"
#include "trimesh.h"

#define FUZZ_CLOUD 1
#define FUZZ_MESH_OFF 2
#define FUZZ_MESH_STL 3
#define FUZZ_MESH_OBJ 4
#define FUZZ_MESH_PLY 5
#define FUZZ_FIT 6
#define FUZZ_PRIMS_HF 7

#ifndef FUZZ_READER
#error "define FUZZ_READER as one of the FUZZ_* numbers"
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Each build uses one of the checks below. */
#if defined(__GNUC__)
#define FUZZ_UNUSED __attribute__((unused))
#else
#define FUZZ_UNUSED
#endif

FUZZ_UNUSED static void check_cloud(const char *data, size_t size)
{
    frep_error e;
    frep_cloud *c = cloud_parse("fuzz", data, size, &e);
    if (!c) return;
    for (size_t i = 0; i < c->n; i++) {
        if (!isfinite(c->x[i]) || !isfinite(c->y[i]) || !isfinite(c->z[i])) abort();
        if (c->has_normals && (!isfinite(c->nx[i]) || !isfinite(c->ny[i]) || !isfinite(c->nz[i])))
            abort();
    }
    cloud_free(c);
}

FUZZ_UNUSED static void check_mesh(const char *data, size_t size, meshio_format fmt)
{
    frep_error e;
    frep_mesh m;
    if (meshio_parse("fuzz", data, size, fmt, &m, &e) != 0) return;
    for (size_t i = 0; i < 3 * m.nverts; i++)
        if (!isfinite(m.v[i])) abort();
    for (size_t i = 0; i < 3 * m.ntris; i++)
        if (m.tri[i] >= m.nverts) abort();
    mesh_free(&m);
}

FUZZ_UNUSED static void check_prims(const char *data, size_t size, int is_fit)
{
    frep_error e;
    prim *p = NULL;
    size_t n = 0;
    if (segment_parse_prims(is_fit ? "fuzz.fit" : "fuzz.hf", data, size, is_fit, &p, &n, &e))
        return;
    for (size_t j = 0; j < n; j++)
        if (prim_degenerate(&p[j])) abort();
    frep_free(p);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    /* The readers parse text with strtol/strtod, so they take data[size] == '\0', as
     * file_read gives it: the input is copied into such a buffer. */
    char *d = malloc(size + 1);
    if (!d) return 0;
    memcpy(d, data, size);
    d[size] = '\0';
#if FUZZ_READER == FUZZ_CLOUD
    check_cloud(d, size);
#elif FUZZ_READER == FUZZ_MESH_OFF
    check_mesh(d, size, MESHIO_OFF);
#elif FUZZ_READER == FUZZ_MESH_STL
    check_mesh(d, size, MESHIO_STL);
#elif FUZZ_READER == FUZZ_MESH_OBJ
    check_mesh(d, size, MESHIO_OBJ);
#elif FUZZ_READER == FUZZ_MESH_PLY
    check_mesh(d, size, MESHIO_PLY);
#elif FUZZ_READER == FUZZ_FIT
    check_prims(d, size, 1);
#elif FUZZ_READER == FUZZ_PRIMS_HF
    check_prims(d, size, 0);
#else
#error "unknown FUZZ_READER"
#endif
    free(d);
    return 0;
}
