/* page.c - the self-contained HTML page of page.h: the JSON of a scene (base64 typed
 * arrays, escaped strings) spliced into the viewer template at its placeholder.
 */
#include "config.h"

#include "alloc.h"
#include "page.h"

#include <math.h>
#include <string.h>

/* The line of view/viewer.html that the scene replaces. */
#define VIEW_PLACEHOLDER "/*@FREP_SCENE@*/"

/* Base64 of a byte stream produced a few bytes at a time. */
typedef struct b64 {
    frep_buf *b;
    unsigned char pend[3];
    int npend;
} b64;

static void b64_flush3(b64 *s)
{
    static const char al[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    const unsigned char *p = s->pend;
    char out[4] = { al[p[0] >> 2], al[((p[0] & 3) << 4) | (p[1] >> 4)],
                    s->npend > 1 ? al[((p[1] & 15) << 2) | (p[2] >> 6)] : '=',
                    s->npend > 2 ? al[p[2] & 63] : '=' };
    buf_put(s->b, out, 4);
    s->npend = 0;
    memset(s->pend, 0, sizeof s->pend);
}

static void b64_byte(b64 *s, unsigned char c)
{
    s->pend[s->npend++] = c;
    if (s->npend == 3) b64_flush3(s);
}

static void b64_u32(b64 *s, uint32_t v)
{
    for (int k = 0; k < 4; k++) b64_byte(s, (unsigned char)(v >> (8 * k)));
}

static void b64_f32(b64 *s, double v)
{
    float f = (float)v;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    b64_u32(s, u);
}

static void b64_end(b64 *s)
{
    if (s->npend) b64_flush3(s);
}

/* A JSON string, safe inside a <script> element ('<' escaped). */
static void json_str(frep_buf *b, const char *s)
{
    if (!s) {
        buf_puts(b, "null");
        return;
    }
    buf_putc(b, '"');
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        if (*p == '"' || *p == '\\') {
            buf_putc(b, '\\');
            buf_putc(b, (char)*p);
        } else if (*p == '\n') buf_puts(b, "\\n");
        else if (*p < 0x20 || *p == '<' || *p == '>' || *p == '&') buf_printf(b, "\\u%04x", *p);
        else buf_putc(b, (char)*p);
    }
    buf_putc(b, '"');
}

/* A number JSON can hold: non-finite values become null. */
static void json_num(frep_buf *b, double v)
{
    if (isfinite(v)) buf_printf(b, "%.9g", v);
    else buf_puts(b, "null");
}

/* n values of xyz arrays (or one interleaved array when y is NULL) as Float32. */
static void f32_xyz(frep_buf *b, size_t n, const double *x, const double *y, const double *z)
{
    b64 s = { b, { 0 }, 0 };
    buf_putc(b, '"');
    for (size_t i = 0; i < n; i++) {
        if (y) {
            b64_f32(&s, x[i]);
            b64_f32(&s, y[i]);
            b64_f32(&s, z[i]);
        } else b64_f32(&s, x[i]);
    }
    b64_end(&s);
    buf_putc(b, '"');
}

/* The mesh: bounds, Float32 positions, Int8 normals, Uint32 corners. */
static void json_mesh(frep_buf *b, const frep_mesh *m)
{
    buf_printf(b, "{\"nv\":%zu,\"nt\":%zu,\"pos\":\"", m->nverts, m->ntris);
    b64 s = { b, { 0 }, 0 };
    for (size_t i = 0; i < 3 * m->nverts; i++) b64_f32(&s, m->v[i]);
    b64_end(&s);
    buf_puts(b, "\",\"nrm\":");
    if (m->n) {
        buf_putc(b, '"');
        for (size_t i = 0; i < 3 * m->nverts; i++) {
            double c = m->n[i];
            c = isfinite(c) ? fmax(-1, fmin(1, c)) : 0;
            b64_byte(&s, (unsigned char)(signed char)lrint(127 * c));
        }
        b64_end(&s);
        buf_putc(b, '"');
    } else buf_puts(b, "null");
    buf_puts(b, ",\"idx\":\"");
    for (size_t i = 0; i < 3 * m->ntris; i++) b64_u32(&s, m->tri[i]);
    b64_end(&s);
    buf_puts(b, "\"}");
}

static void json_points(frep_buf *b, const view_scene *s)
{
    buf_printf(b, "{\"n\":%zu,\"pos\":", s->npoints);
    f32_xyz(b, s->npoints, s->px, s->py, s->pz);
    buf_puts(b, ",\"d\":");
    if (s->pdist) {
        /* Float32 keeps +-inf (no gradient) as it is; the viewer saturates it. */
        f32_xyz(b, s->npoints, s->pdist, NULL, NULL);
    } else buf_puts(b, "null");
    buf_puts(b, ",\"scale\":");
    json_num(b, s->pscale);
    buf_putc(b, '}');
}

void view_scene_json(frep_buf *b, const view_scene *s)
{
    buf_printf(b, "{\"version\":%u,\"name\":", s->version);
    json_str(b, s->name);
    buf_puts(b, ",\"units\":");
    json_str(b, s->units ? s->units : "model units");
    buf_puts(b, ",\"info\":");
    json_str(b, s->info);
    buf_puts(b, ",\"source\":");
    json_str(b, s->source);
    buf_puts(b, ",\"diag\":");
    json_str(b, s->diag);
    buf_puts(b, ",\"params\":[");
    for (size_t i = 0; i < s->nparams; i++) {
        buf_puts(b, i ? ",[" : "[");
        json_str(b, s->pnames[i]);
        buf_putc(b, ',');
        json_num(b, s->pvalues[i]);
        buf_putc(b, ']');
    }
    buf_puts(b, "],\"mesh\":");
    if (s->mesh && s->mesh->ntris) json_mesh(b, s->mesh);
    else buf_puts(b, "null");
    buf_puts(b, ",\"vdist\":");
    if (s->mesh && s->mesh->ntris && s->vdist) {
        buf_puts(b, "{\"d\":");
        f32_xyz(b, s->mesh->nverts, s->vdist, NULL, NULL);
        buf_puts(b, ",\"scale\":");
        json_num(b, s->vscale);
        buf_putc(b, '}');
    } else buf_puts(b, "null");
    buf_puts(b, ",\"points\":");
    if (s->npoints && s->px) json_points(b, s);
    else buf_puts(b, "null");
    buf_putc(b, '}');
}

char *view_page(const view_scene *s, int watch, size_t *len, frep_error *e)
{
    const char *at = strstr(view_template, VIEW_PLACEHOLDER);
    frep_buf b = FREP_BUF_INIT;
    if (!at) at = view_template + strlen(view_template);
    buf_put(&b, view_template, (size_t)(at - view_template));
    buf_printf(&b, "var FREP_WATCH = %d;\nvar FREP_SCENE = ", watch ? 1 : 0);
    view_scene_json(&b, s);
    buf_puts(&b, ";\n");
    if (*at) buf_puts(&b, at + strlen(VIEW_PLACEHOLDER));
    char *page = buf_finish(&b, len);
    if (!page) frep_error_nomem(e);
    return page;
}

int view_write_page(FILE *f, const view_scene *s, frep_error *e)
{
    size_t len;
    char *page = view_page(s, 0, &len, e);
    if (!page) return -1;
    int rc = fwrite(page, 1, len, f) == len ? 0 : -1;
    frep_free(page);
    if (rc != 0) return frep_error_set(e, FREP_EIO, "write failed");
    return 0;
}
