/* test_cloud.c - unit tests of geom/cloud.c: .xyz and PLY readers (every format,
 * malformed input with its message), writers and their round trip, bounding box; and
 * of the whole-file reader they use (runtime/file.c); the readers' fast number
 * conversion (geom/decimal.c) against strtod.
 */
#include <errno.h>
#include <float.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "alloc.h"
#include "cloud.h"
#include "decimal.h"
#include "file.h"
#include "tap.h"

static frep_cloud *parse(const char *s, frep_error *err)
{
    return cloud_parse("t.xyz", s, strlen(s), err);
}

/* The parser must fail with exactly this message. */
static void expect_error(const char *data, size_t len, const char *want, const char *what)
{
    frep_error err;
    frep_cloud *c = cloud_parse("t.xyz", data, len, &err);
    ok(c == NULL, "%s: rejected", what);
    is_str(err.msg[0] ? err.msg : "(none)", want, "%s: message", what);
    cloud_free(c);
}

static void test_xyz(void)
{
    frep_error err;
    frep_cloud *c = parse("# header\n1 2 3\n\n  4\t5 6  # trailing\r\n-1e-3,0.5,7\n", &err);
    ok(c != NULL, "xyz with comments, blank lines, tabs, commas, CRLF");
    if (c) {
        is_int(c->n, 3, "three points");
        ok(!c->has_normals, "no normals");
        is_double(c->x[1], 4, 0, "x of point 2");
        is_double(c->z[1], 6, 0, "z of point 2");
        is_double(c->x[2], -1e-3, 0, "exponent notation");
    }
    cloud_free(c);

    c = parse("0 0 0 0 0 1\n1 0 0 0 0 -2\n", &err);
    ok(c && c->has_normals && c->n == 2, "six columns give normals");
    if (c) {
        is_double(c->nz[1], -2, 0, "normal kept as written");
        is_int(cloud_normalize_normals(c), 0, "no zero normals");
        is_double(c->nz[1], -1, 1e-15, "normalized");
    }
    cloud_free(c);

    const char *bad5 = "1 2 3\n1 2 3 4 5\n";
    expect_error(bad5, strlen(bad5), "t.xyz:2: expected 3 or 6 numbers, got 5", "5 numbers");
    const char *mixed = "1 2 3 0 0 1\n\n4 5 6\n";
    expect_error(mixed, strlen(mixed), "t.xyz:3: expected 6 numbers as on line 1, got 3",
                 "mixed columns");
    const char *nan = "1 2 3\n4 nan 6\n";
    expect_error(nan, strlen(nan), "t.xyz:2: number 2 is not finite", "NaN");
    const char *inf = "1 2 -inf\n";
    expect_error(inf, strlen(inf), "t.xyz:1: number 3 is not finite", "inf");
    const char *word = "1 2 3\n\n1 x2 3\n";
    expect_error(word, strlen(word), "t.xyz:3: 'x2' is not a number", "word");
    expect_error("# only a comment\n\n", 18, "t.xyz: no points", "empty");
    expect_error("", 0, "t.xyz: no points", "zero bytes");
}

/* decimal_parse against strtod on one string: 0 when it declines or gives strtod's bits
 * (NaN never: it declines "nan"), 1 when the bits differ. *fast counts conversions. */
static int decimal_differs(const char *t, long *fast)
{
    double v = 0, want = strtod(t, NULL);
    if (!decimal_parse(t, t + strlen(t), &v)) return 0;
    ++*fast;
    if (memcmp(&v, &want, sizeof v) == 0) return 0;
    diag("decimal_parse(\"%s\") = %.17g, strtod %.17g", t, v, want);
    return 1;
}

/* Random strings of every kind the readers meet: round-trip printing (17 digits) and
 * shorter ones of random doubles over 60 decades, fixed notation, random digit strings
 * with the point anywhere and exponents around the exact range, and the neighbours of
 * ties between two doubles (a midpoint written to 17-19 digits, and 1-2 units away in
 * the last digit), where rounding twice through a wider format goes wrong. */
static void random_decimal(uint64_t *st, char *t, size_t size)
{
    int kind = (int)tap_urand(st, 0, 5);
    double mag = pow(10, tap_urand(st, -30, 30)) * (tap_urand(st, 0, 1) < 0.5 ? -1 : 1);
    double u = tap_urand(st, 0, 1);
    if (kind == 0) {
        snprintf(t, size, "%.17g", mag * u);
    } else if (kind == 1) {
        snprintf(t, size, "%.*g", (int)tap_urand(st, 1, 20), mag * u);
    } else if (kind == 2) {
        snprintf(t, size, "%.*f", (int)tap_urand(st, 0, 13), tap_urand(st, -1e4, 1e4));
    } else if (kind == 3) {
        int nd = (int)tap_urand(st, 1, 21), dot = (int)tap_urand(st, 0, nd + 2);
        size_t k = 0;
        if (tap_urand(st, 0, 1) < 0.3) t[k++] = tap_urand(st, 0, 1) < 0.5 ? '-' : '+';
        for (int i = 0; i < nd; i++) {
            if (i == dot) t[k++] = '.';
            t[k++] = (char)('0' + (int)tap_urand(st, 0, 10));
        }
        if (dot == nd) t[k++] = '.';
        t[k] = '\0';
        if (tap_urand(st, 0, 1) < 0.6)
            snprintf(t + k, size - k, "e%d", (int)tap_urand(st, -35, 35));
    } else {
        /* a double d and the tie halfway to the next, 17-19 significant digits */
        double d = fabs(mag) * (1 + u), next = nextafter(d, INFINITY);
        long double mid = ((long double)d + (long double)next) / 2;
        char m[64];
        snprintf(m, sizeof m, "%.*Le", (int)tap_urand(st, 16, 19), mid);
        char *e = strchr(m, 'e');
        if (e && tap_urand(st, 0, 1) < 0.5 && e[-1] >= '2' && e[-1] <= '7')
            e[-1] = (char)(e[-1] + (tap_urand(st, 0, 1) < 0.5 ? -1 : 1));
        snprintf(t, size, "%s", m);
    }
}

static void test_decimal(void)
{
    /* Edge cases: zeros, the ends of the exact ranges, ties and their neighbours, forms
     * it must leave to strtod. */
    static const char *const edge[] = {
        "0", "-0", "+0", "0.0", "-0.0e5", "0e99999", "00000", "1", "-1", "1.", ".5", "-.5",
        "+.5e1", "0.1", "0.2", "0.3", "1e22", "1e23", "1e-22", "1e-23", "1e27", "1e-27",
        "1e28", "9007199254740992", "9007199254740993", "9007199254740994",
        "9007199254740995", "9007199254740993e-5", "18014398509481985",
        "18014398509481986", "36028797018963971", "9999999999999999999",
        "10000000000000000000", "18446744073709551615", "4.9406564584124654e-324",
        "2.2250738585072014e-308", "1.7976931348623157e308", "1.7976931348623159e308",
        "1e400", "1e-400", "-1.6843108809570762", "4.0000000143067167",
        "0.4195673980991757", "2.3290669287588697e-17", "123456789012345678e-10",
        "0.000000000000000000000000000001", "1.00000000000000011102230246251565404",
        "1.0000000000000002220446049250313", "1.00000000000000033306690738754696",
        "9.999999999999999e22", "8.98846567431158e307", "1e00000000000000000000000000022",
        "1e-000000000000000000022", "1E5", "1e+5", "1e-5",
    };
    long fast = 0;
    int bad = 0;
    for (size_t i = 0; i < sizeof edge / sizeof *edge; i++) bad += decimal_differs(edge[i], &fast);
    is_int(bad, 0, "decimal_parse gives strtod's bits on %zu edge cases (%ld converted)",
           sizeof edge / sizeof *edge, fast);
    static const char *const decline[] = {
        "", "+", "-", ".", "-.", "e5", ".e5", "1e", "1e+", "1e-", "1..2", "1.2.3", "1e5.5",
        "1e5e5", "0x10", "0x1p3", "inf", "-inf", "nan", "infinity", "1,5", "1 ", " 1",
        "1f", "--1", "+-1", "12345678901234567890", "1.2345678901234567890",
        "1e999999999999999999999", "1e-999999999999999999999", "5e100000", "1e-28",
    };
    int took = 0;
    for (size_t i = 0; i < sizeof decline / sizeof *decline; i++) {
        double v = 42;
        const char *t = decline[i];
        if (decimal_parse(t, t + strlen(t), &v) || v != 42) {
            diag("decimal_parse took \"%s\"", t);
            took++;
        }
    }
    is_int(took, 0, "decimal_parse leaves %zu other forms to strtod",
           sizeof decline / sizeof *decline);
    double v = 0;
    ok(decimal_parse("-1.25e-3", "-1.25e-3" + 8, &v) && v == -1.25e-3 &&
           decimal_parse("0.4195673980991757", "0.4195673980991757" + 18, &v) &&
           v == 0.4195673980991757 && decimal_parse("-0", "-0" + 2, &v) && signbit(v),
       "Clinger's path converts short decimals and -0");
    ok(decimal_parse("12.5xyz", "12.5xyz" + 4, &v) && v == 12.5,
       "decimal_parse stops at the end it is given");

    /* Random strings. */
    uint64_t st = 0x9e3779b97f4a7c15ULL;
    char t[80];
    const long count = 1000000;
    fast = 0;
    bad = 0;
    for (long i = 0; i < count && bad < 10; i++) {
        random_decimal(&st, t, sizeof t);
        bad += decimal_differs(t, &fast);
    }
    is_int(bad, 0, "decimal_parse gives strtod's bits on %ld random strings (%ld converted)",
           count, fast);
    ok(fast > count / 2, "most random strings take a fast path (%ld of %ld)", fast, count);

    /* Through the reader: a cloud of such numbers holds strtod's values. */
    size_t cap = 64 * 3 * 600, len = 0;
    char *text = frep_malloc(cap);
    double want[3 * 600];
    for (int i = 0; i < 3 * 600; i++) {
        random_decimal(&st, t, sizeof t);
        want[i] = strtod(t, NULL);
        len += (size_t)snprintf(text + len, cap - len, "%s%s", t, i % 3 == 2 ? "\n" : " ");
    }
    frep_error err;
    frep_cloud *c = cloud_parse("t.xyz", text, len, &err);
    int same = c != NULL && c->n == 600;
    for (size_t i = 0; same && i < 600; i++)
        same = memcmp(&c->x[i], &want[3 * i], 8) == 0 &&
               memcmp(&c->y[i], &want[3 * i + 1], 8) == 0 &&
               memcmp(&c->z[i], &want[3 * i + 2], 8) == 0;
    ok(same, "an .xyz cloud of random numbers reads to strtod's bits");
    cloud_free(c);
    frep_free(text);
}

static void test_ply_ascii(void)
{
    const char *s =
        "ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\n"
        "property float x\nproperty float y\nproperty float z\nproperty uchar red\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "1 2 3 255 0 0 1\n4 5 6 0 1 0 0\n3 0 1 1\n";
    frep_error err;
    frep_cloud *c = cloud_parse("t.ply", s, strlen(s), &err);
    ok(c != NULL, "ascii PLY with colour and faces: %s", err.msg[0] ? err.msg : "ok");
    if (c) {
        is_int(c->n, 2, "2 vertices");
        ok(c->has_normals, "normals");
        is_double(c->y[1], 5, 0, "y");
        is_double(c->nx[0], 0, 0, "nx skips colour");
        is_double(c->nx[1], 1, 0, "nx of vertex 1");
    }
    cloud_free(c);

    /* Header errors name the line. */
    const char *h1 = "ply\nformat ascii 1.0\nelement vertex 1\nproperty flot x\nend_header\n";
    c = cloud_parse("t.ply", h1, strlen(h1), &err);
    ok(!c, "unknown type rejected");
    is_str(err.msg[0] ? err.msg : "", "t.ply:4: unknown property type 'flot'", "message with line");
    const char *h2 = "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                     "property float y\nend_header\n1 2\n";
    c = cloud_parse("t.ply", h2, strlen(h2), &err);
    ok(!c, "missing z rejected");
    is_str(err.msg[0] ? err.msg : "", "t.ply: vertex element lacks x, y or z", "message");
    const char *h3 = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                     "property float y\nproperty float z\nend_header\n1 2 3\n4 5 6\n";
    c = cloud_parse("t.ply", h3, strlen(h3), &err);
    ok(!c, "truncated data rejected");
    is_str(err.msg[0] ? err.msg : "", "t.ply:10: data ends in vertex 2 of 3", "message");
    const char *h4 = "ply\nformat ascii 1.0\nelement vertex 1\n";
    c = cloud_parse("t.ply", h4, strlen(h4), &err);
    ok(!c, "header without end rejected");
    is_str(err.msg[0] ? err.msg : "", "t.ply:3: header ends without end_header", "message");
    const char *h5 = "ply\nformat ascii 1.0\nelement vertex 99999999999\nend_header\n";
    c = cloud_parse("t.ply", h5, strlen(h5), &err);
    ok(!c, "absurd vertex count rejected before allocating");
    /* A count the data cannot hold (one byte a property at least) is refused before
     * the vertices are reserved: 200 million floats over 12 bytes. */
    const char h6[] = "ply\nformat binary_little_endian 1.0\nelement vertex 200000000\n"
                      "property float x\nproperty float y\nproperty float z\nend_header\n"
                      "0123456789ab";
    c = cloud_parse("t.ply", h6, sizeof h6 - 1, &err);
    ok(!c, "a vertex count the data cannot hold rejected");
    is_str(err.msg[0] ? err.msg : "",
           "t.ply: 200000000 vertices declared, more than the 12 bytes of data left can hold",
           "message");
}

/* An element without properties holds no data, however many items it declares (the
 * fuzzer found the reader looping over 2^64 empty items). */
static void test_ply_empty_element(void)
{
    static const char *fmt[] = {"ascii", "binary_little_endian"};
    for (int i = 0; i < 2; i++) {
        char s[256];
        size_t n = (size_t)snprintf(s, sizeof s,
                                    "ply\nformat %s 1.0\nelement vertex 1\nproperty uchar x\n"
                                    "property uchar y\nproperty uchar z\n"
                                    "element junk 18446744073709551615\nend_header\n",
                                    fmt[i]);
        if (i == 0) n += (size_t)snprintf(s + n, sizeof s - n, "1 2 3\n");
        else s[n++] = 1, s[n++] = 2, s[n++] = 3;
        frep_error err;
        frep_cloud *c = cloud_parse("e.ply", s, n, &err);
        ok(c && c->n == 1 && c->z[0] == 3, "%s PLY with a property-less element of 2^64 items: %s",
           fmt[i], c ? "read" : err.msg);
        cloud_free(c);
    }
}

/* Binary PLY built by hand: float x y z, a uchar we skip, double nz (no nx/ny: no
 * normals), in either byte order. */
static size_t put(unsigned char *b, const void *v, size_t n, int big)
{
    const unsigned char *s = v;
    uint16_t one = 1;
    int host_big = *(const unsigned char *)&one == 0;
    for (size_t i = 0; i < n; i++) b[i] = (big != host_big) ? s[n - 1 - i] : s[i];
    return n;
}

static void test_ply_binary(int big)
{
    unsigned char buf[512];
    const char *hdr = big ? "ply\nformat binary_big_endian 1.0\n"
                          : "ply\nformat binary_little_endian 1.0\n";
    const char *rest = "element vertex 2\nproperty float x\nproperty float y\n"
                       "property float z\nproperty uchar q\nproperty double nz\nend_header\n";
    size_t n = 0;
    memcpy(buf, hdr, strlen(hdr)); n += strlen(hdr);
    memcpy(buf + n, rest, strlen(rest)); n += strlen(rest);
    for (int i = 0; i < 2; i++) {
        float xyz[3] = {1.5f + (float)i, -2.0f, 0.25f};
        for (int k = 0; k < 3; k++) n += put(buf + n, &xyz[k], 4, big);
        buf[n++] = 7;
        double nz = 3.0;
        n += put(buf + n, &nz, 8, big);
    }
    frep_error err;
    frep_cloud *c = cloud_parse("b.ply", (const char *)buf, n, &err);
    ok(c != NULL, "binary %s PLY: %s", big ? "big" : "little", err.msg[0] ? err.msg : "ok");
    if (c) {
        is_int(c->n, 2, "2 vertices");
        ok(!c->has_normals, "partial normals ignored");
        is_double(c->x[1], 2.5, 0, "x of vertex 1");
        is_double(c->y[0], -2, 0, "y");
        is_double(c->z[1], 0.25, 0, "z");
    }
    cloud_free(c);
    c = cloud_parse("b.ply", (const char *)buf, n - 3, &err);
    ok(!c, "truncated binary rejected");
    is_str(err.msg[0] ? err.msg : "", "b.ply: binary data ends or is corrupt in vertex 1 of 2",
           "truncation message");
}

static void test_roundtrip(int ply)
{
    frep_cloud *c = cloud_new(1);
    for (int i = 0; i < 100; i++) {
        double p[3] = {i * 0.1, 1.0 / (i + 1), -i * 1e-7};
        double nrm[3] = {0.1, 0.2, -0.3 * i};
        cloud_push(c, p, nrm);
    }
    FILE *f = tmpfile();
    ok(f != NULL, "tmpfile");
    if (!f) { cloud_free(c); return; }
    int rc = ply ? cloud_write_ply(f, c) : cloud_write_xyz(f, c);
    is_int(rc, 0, "%s written", ply ? "PLY" : "xyz");
    long len = ftell(f);
    rewind(f);
    char *data = malloc((size_t)len);
    size_t got = fread(data, 1, (size_t)len, f);
    fclose(f);
    frep_error err;
    frep_cloud *d = cloud_parse("rt", data, got, &err);
    ok(d && d->n == 100 && d->has_normals, "%s read back", ply ? "PLY" : "xyz");
    int same = d != NULL;
    for (size_t i = 0; d && i < 100 && same; i++)
        same = d->x[i] == c->x[i] && d->y[i] == c->y[i] && d->z[i] == c->z[i] &&
               d->nx[i] == c->nx[i] && d->ny[i] == c->ny[i] && d->nz[i] == c->nz[i];
    ok(same, "%s round trip is exact", ply ? "PLY" : "xyz");
    cloud_free(d);
    cloud_free(c);
    free(data);
}

static void test_bbox(void)
{
    frep_cloud *c = cloud_new(0);
    is_double(cloud_diagonal(c), 0, 0, "empty cloud: zero diagonal");
    double a[3] = {1, 2, 3}, b[3] = {4, -2, 3};
    cloud_push(c, a, NULL);
    is_double(cloud_diagonal(c), 0, 0, "one point: zero diagonal");
    cloud_push(c, b, NULL);
    double lo[3], hi[3];
    cloud_bbox(c, lo, hi);
    is_double(lo[1], -2, 0, "lo y");
    is_double(hi[0], 4, 0, "hi x");
    is_double(cloud_diagonal(c), 5, 1e-15, "3-4-5 diagonal");
    cloud_free(c);
}

/* A fresh file in TMPDIR (or /tmp) holding len bytes of data; its path in path. */
static int temp_file(char *path, size_t size, const char *data, size_t len)
{
    const char *dir = getenv("TMPDIR");
    snprintf(path, size, "%s/frep_test_file_XXXXXX", dir && *dir ? dir : "/tmp");
    int fd = mkstemp(path);
    if (fd < 0) return -1;
    ssize_t w = write(fd, data, len);
    close(fd);
    return w == (ssize_t)len ? 0 : -1;
}

static void test_file_read(void)
{
    char path[512];
    const char text[] = "1 2 3\n4 5 6\n";
    size_t tl = sizeof text - 1;
    if (!ok(temp_file(path, sizeof path, text, tl) == 0, "file: temporary file")) return;
    frep_file f;
    frep_error e;
    frep_error_init(&e);
    ok(frep_file_read(&f, path, FREP_FILE_MAX_BYTES, 0, &e) == 0 && f.len == tl &&
           memcmp(f.data, text, tl) == 0 && f.data[tl] == '\0',
       "file: whole file read, NUL-ended");
    frep_free(f.data);
    ok(frep_file_read(&f, path, tl, 0, &e) == 0 && f.len == tl, "file: exactly the limit");
    frep_free(f.data);
    ok(frep_file_read(&f, path, tl - 1, 0, &e) == -1 && e.code == FREP_ELIMIT && !f.data,
       "file: over the limit rejected");
    char want[64];
    snprintf(want, sizeof want, "larger than %zu bytes", tl - 1);
    is_str(e.msg, want, "file: limit message");
    frep_cloud *c = NULL;
    frep_error err;
    c = cloud_read(path, &err);
    ok(c && c->n == 2, "file: cloud_read reads the cloud");
    cloud_free(c);
    unlink(path);

    frep_error_init(&e);
    ok(frep_file_read(&f, path, FREP_FILE_MAX_BYTES, 0, &e) == -1 && f.open_failed &&
           e.code == FREP_EIO,
       "file: missing file fails to open");
    is_str(e.msg, strerror(ENOENT), "file: errno's reason");
    c = cloud_read(path, &err);
    char want2[600];
    snprintf(want2, sizeof want2, "cannot read %s: %s", path, strerror(ENOENT));
    ok(!c, "file: cloud_read of a missing file fails");
    is_str(err.msg[0] ? err.msg : "", want2, "file: cloud_read message");

    frep_error_init(&e);
    const char *dir = getenv("TMPDIR");
    ok(frep_file_read(&f, dir && *dir ? dir : "/tmp", FREP_FILE_MAX_BYTES, 0, &e) == -1 &&
           !f.open_failed && e.code == FREP_EIO,
       "file: a directory opens but cannot be read");

    if (temp_file(path, sizeof path, "", 0) == 0) {
        frep_error_init(&e);
        ok(frep_file_read(&f, path, FREP_FILE_MAX_BYTES, 0, &e) == 0 && f.len == 0 && f.data &&
               f.data[0] == '\0',
           "file: empty file gives an empty string");
        frep_free(f.data);
        unlink(path);
    }
}

int main(void)
{
    test_file_read();
    test_xyz();
    test_decimal();
    test_ply_ascii();
    test_ply_binary(0);
    test_ply_binary(1);
    test_ply_empty_element();
    test_roundtrip(0);
    test_roundtrip(1);
    test_bbox();
    return done_testing();
}
