/* test_view.c - unit tests of view/: the distances and the scale chosen from them
 * (distance.c), the page and its scene JSON (page.c), the loopback server (serve.c)
 * talked to through a real socket in this process.
 */
#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "alloc.h"
#include "distance.h"
#include "frep.h"
#include "page.h"
#include "serve.h"
#include "tap.h"

static void test_scale(void)
{
    is_double(view_nice_ceil(0.013), 0.02, 1e-15, "0.013 rounds up to 0.02");
    is_double(view_nice_ceil(0.1), 0.1, 1e-15, "0.1 stays");
    is_double(view_nice_ceil(3), 5, 1e-12, "3 rounds up to 5");
    is_double(view_nice_ceil(7), 10, 1e-12, "7 rounds up to 10");
    double d[100], s = 0;
    frep_error e;
    frep_error_init(&e);
    for (int i = 0; i < 100; i++) d[i] = (i % 2 ? -1 : 1) * 0.001 * (i + 1);
    d[7] = INFINITY;
    ok(view_auto_scale(d, 100, 0.95, 1, 9, &s, &e) == 0, "auto scale");
    /* 99 finite |d| 0.001..0.1 without 0.008: the 95th percentile is 0.095 -> 0.1 */
    is_double(s, 0.1, 1e-15, "95th percentile of |d| rounded up, infinities left out");
    double z[3] = { 0, 0, INFINITY };
    view_auto_scale(z, 3, 0.95, 1, 9, &s, &e);
    is_double(s, 9, 0, "no positive finite value: the fallback");
}

static frep_program *compile(const char *src)
{
    frep_compile_options o;
    frep_compile_options_init(&o);
    return frep_compile("t.hf", src, strlen(src), &o, NULL, NULL);
}

static void test_point_distances(void)
{
    frep_program *p = compile("my_model(x[3], a[1]) { my_model = 1 - sqrt(x[1]^2 + x[2]^2 + x[3]^2); }");
    ok(p != NULL, "a cone-distance sphere compiles");
    if (!p) return;
    double x[3] = { 2, 0.5, 1 }, y[3] = { 0, 0, 1 }, z[3] = { 0, 0, 1 }, d[3];
    frep_error e;
    frep_error_init(&e);
    ok(view_point_distances(p, 0, 3, x, y, z, 1, d, NULL, &e) == 0, "point distances");
    is_double(d[0], -1, 1e-12, "outside at distance 1: -1");
    is_double(d[1], 0.5, 1e-12, "inside at depth 0.5: +0.5");
    is_double(d[2], 1 - sqrt(3), 1e-12, "outside at (1,1,1): 1 - sqrt(3)");
    frep_program_free(p);
}

/* The unit tetrahedron with outward faces. */
static double tet_v[] = { 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1 };
static uint32_t tet_t[] = { 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3 };

static void test_mesh_distances(void)
{
    frep_mesh m = { 4, 4, tet_v, NULL, tet_t };
    double x[3] = { 0.1, 0.2, -1 }, y[3] = { 0.1, 0.2, 0.3 }, z[3] = { 0.1, -0.5, 0.3 }, d[3];
    frep_error e;
    frep_error_init(&e);
    ok(view_mesh_distances(&m, 3, x, y, z, d, &e) == 0, "mesh distances");
    is_double(d[0], 0.1, 1e-12, "inside, 0.1 from three faces: +0.1");
    is_double(d[1], -0.5, 1e-12, "below the base: -0.5");
    is_double(d[2], -1, 1e-12, "beside the face x = 0: -1");
    double vd[4];
    double cx[2] = { 0, 1 }, cy[2] = { 0, 0 }, cz[2] = { 0, 0 };
    ok(view_vertex_distances(&m, 2, cx, cy, cz, vd, &e) == 0, "vertex distances");
    is_double(vd[0], 0, 0, "vertex on a point");
    is_double(vd[2], 1, 1e-12, "vertex (0,1,0) 1 from the nearest point");
    ok(view_vertex_distances(&m, 0, cx, cy, cz, vd, &e) != 0 && e.code == FREP_EINPUT,
       "an empty cloud is refused");
}

/* Decode base64 (no checks: the test gives what the writer made). */
static size_t unbase64(const char *s, size_t n, unsigned char *out)
{
    static const char al[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    size_t o = 0;
    uint32_t acc = 0;
    int bits = 0;
    for (size_t i = 0; i < n && s[i] != '='; i++) {
        acc = (acc << 6) | (uint32_t)(strchr(al, s[i]) - al);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[o++] = (unsigned char)(acc >> bits);
        }
    }
    return o;
}

/* IEEE 754 binary16 encodings (the standard's examples: 1 = 0x3c00, the largest
 * finite 65504 = 0x7bff, the smallest normal 2^-14 = 0x0400, 0.1 rounds to 0x2e66). */
static void test_half(void)
{
    ok(view_half(1.0) == 0x3c00 && view_half(-2.0) == 0xc000, "half: 1 and -2");
    ok(view_half(0.1) == 0x2e66, "half: 0.1 rounded to nearest: %04x", view_half(0.1));
    ok(view_half(65504) == 0x7bff && view_half(65519) == 0x7bff && view_half(65520) == 0x7c00,
       "half: the largest finite value, and infinity from 65520 up");
    ok(view_half(INFINITY) == 0x7c00 && view_half(-INFINITY) == 0xfc00 && (view_half(NAN) & 0x7fff) > 0x7c00,
       "half: infinities and NaN");
    ok(view_half(ldexp(1, -14)) == 0x0400 && view_half(ldexp(3, -24)) == 0x0003,
       "half: the smallest normal, a subnormal");
    ok(view_half(1e-12) == 0x0001 && view_half(-1e-12) == 0x8001 && view_half(0.0) == 0,
       "half: a tiny non-zero value keeps its sign, zero stays zero");
}

static void test_page(void)
{
    frep_mesh m = { 4, 4, tet_v, NULL, tet_t };
    double px[2] = { 0.25, 1.25 }, py[2] = { 0.5, 0.5 }, pz[2] = { -0.125, 1 }, pd[2] = { 0.5, -1 };
    view_scene s;
    memset(&s, 0, sizeof s);
    s.name = "t\"</script>.hf";
    s.mesh = &m;
    s.npoints = 2;
    s.px = px;
    s.py = py;
    s.pz = pz;
    s.pdist = pd;
    s.pscale = 0.5;
    s.source = "a\nb";
    static const unsigned char rgb[12] = { 255, 0, 0, 0, 255, 0, 0, 0, 255, 10, 20, 30 };
    s.vrgb = rgb;
    s.diag = "w.hf:1:2: warning: x\n";
    s.cdiag = "c.xyz:3: y\n";
    frep_buf b = FREP_BUF_INIT;
    view_scene_json(&b, &s);
    size_t len;
    char *j = buf_finish(&b, &len);
    ok(j != NULL, "scene JSON");
    if (!j) return;
    ok(strstr(j, "\"name\":\"t\\\"\\u003c/script\\u003e.hf\"") != NULL, "names escaped for <script>");
    ok(strstr(j, "\"source\":\"a\\nb\"") != NULL, "newlines escaped");
    ok(strstr(j, "\"nv\":4,\"nt\":4") != NULL, "mesh counts");
    const char *pos = strstr(j, "\"points\":{\"n\":2,\"lo\":[0.25,0.5,-0.125],\"hi\":[1.25,0.5,1],\"pos\":\"");
    ok(pos != NULL, "points with their bounds");
    if (pos) {
        pos = strstr(pos, "\"pos\":\"") + 7;
        unsigned char raw[16];
        size_t n = unbase64(pos, (size_t)(strchr(pos, '"') - pos), raw);
        static const unsigned char want[12] = { 0, 0, 0, 0, 0, 0, 255, 255, 0, 0, 255, 255 };
        ok(n == 12 && memcmp(raw, want, 12) == 0,
           "positions as little-endian Uint16 fractions of the bounds");
    }
    ok(strstr(j, "\"diag\":\"w.hf:1:2: warning: x\\nc.xyz:3: y\\n\",\"failed\":false") != NULL,
       "the model's messages, then the cloud's; the build did not fail");
    const char *col = strstr(j, "\"rgb\":\"");
    ok(col != NULL, "vertex colours");
    if (col) {
        col += 7;
        unsigned char raw[16];
        size_t n = unbase64(col, (size_t)(strchr(col, '"') - col), raw);
        ok(n == 12 && memcmp(raw, rgb, 12) == 0, "colours as Uint8 red, green, blue a vertex");
    }
    const char *idx = strstr(j, "\"idx\":\"");
    ok(idx != NULL, "triangle corners");
    if (idx) {
        idx += 7;
        unsigned char raw[16];
        size_t n = unbase64(idx, (size_t)(strchr(idx, '"') - idx), raw);
        /* corners 0 2 1 0 1 3 0 3 2 1 2 3: differences 0 +2 -1 -1 +1 +2 -3 +3 -1 -1 +1 +1 */
        static const unsigned char want[12] = { 0, 4, 1, 1, 2, 4, 5, 6, 1, 1, 2, 2 };
        ok(n == 12 && memcmp(raw, want, 12) == 0, "corners as zigzag varint differences");
    }
    frep_free(j);
    frep_error e;
    frep_error_init(&e);
    char *page = view_page(&s, 1, &len, &e);
    ok(page && strncmp(page, "<!DOCTYPE html>", 15) == 0, "the page is the template");
    ok(page && strstr(page, "var FREP_WATCH = 1;\nvar FREP_SCENE = {") != NULL, "with the scene");
    ok(page && !strstr(page, "/*@FREP_SCENE@*/"), "in place of the placeholder");
    ok(page && strstr(page, "</html>") != NULL, "and the rest of the template");
    ok(page && !strstr(page, "http://") && !strstr(page, "https://"), "nothing from the network");
    frep_free(page);
}

/* ---- the server ---- */

static const char big_body[] = "the page";

static void route(void *user, const char *path, view_reply *r)
{
    int *calls = user;
    ++*calls;
    if (strcmp(path, "/page") == 0) *r = (view_reply){ 200, "text/html", big_body, 8 };
}

/* Send req to the server, step it until it answered, return the reply (static). */
static const char *ask(view_server *s, const char *req, int *calls)
{
    static char reply[4096];
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a;
    memset(&a, 0, sizeof a);
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    a.sin_port = htons((uint16_t)view_server_port(s));
    reply[0] = '\0';
    if (fd < 0 || connect(fd, (struct sockaddr *)&a, sizeof a) != 0) return reply;
    send(fd, req, strlen(req), 0);
    for (int i = 0; i < 50 && view_server_step(s, 20, route, calls) == 0; i++) {
    }
    size_t n = 0;
    ssize_t k;
    while (n < sizeof reply - 1 && (k = recv(fd, reply + n, sizeof reply - 1 - n, 0)) > 0)
        n += (size_t)k;
    reply[n] = '\0';
    close(fd);
    return reply;
}

static void test_server(void)
{
    frep_error e;
    frep_error_init(&e);
    view_server *s = view_server_open(0, &e);
    ok(s != NULL, "listen on 127.0.0.1, any free port");
    if (!s) {
        diag("%s", e.msg);
        return;
    }
    ok(view_server_port(s) > 0, "the port is known");
    int calls = 0;
    const char *r = ask(s, "GET /page HTTP/1.1\r\nHost: x\r\n\r\n", &calls);
    ok(strncmp(r, "HTTP/1.0 200 OK\r\n", 17) == 0, "GET /page: 200");
    ok(strstr(r, "Content-Length: 8\r\n") && strstr(r, "\r\n\r\nthe page"), "the body");
    ok(strstr(r, "Cache-Control: no-store") != NULL, "not cached");
    r = ask(s, "GET /nothing HTTP/1.0\r\n\r\n", &calls);
    ok(strncmp(r, "HTTP/1.0 404", 12) == 0, "unknown path: 404");
    r = ask(s, "POST /page HTTP/1.0\r\n\r\n", &calls);
    ok(strncmp(r, "HTTP/1.0 400", 12) == 0, "not a GET: 400");
    is_int(calls, 2, "only the GETs reached the routes");
    char *huge = malloc(VIEW_MAX_REQUEST + 64);
    if (huge) {
        /* exactly the limit, so the server reads all of it before it answers */
        memset(huge, 'a', VIEW_MAX_REQUEST);
        memcpy(huge, "GET /", 5);
        huge[VIEW_MAX_REQUEST] = '\0';
        r = ask(s, huge, &calls);
        ok(strncmp(r, "HTTP/1.0 431", 12) == 0, "a request past VIEW_MAX_REQUEST: 431");
        free(huge);
    }
    view_server *t = view_server_open(view_server_port(s), &e);
    ok(t == NULL && e.code == FREP_EIO && strstr(e.msg, "cannot listen on 127.0.0.1:"),
       "a port in use is an error: %s", e.msg);
    view_server_close(t);
    view_server_close(s);
}

int main(void)
{
    test_scale();
    test_point_distances();
    test_mesh_distances();
    test_half();
    test_page();
    test_server();
    return done_testing();
}
