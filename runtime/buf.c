/* buf.c - the growable byte buffer (runtime/buf.h). */
#include "buf.h"
#include "alloc.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

/* Room for n more bytes and the NUL; capacity doubles from 128. */
static int buf_reserve(frep_buf *b, size_t n)
{
    if (b->failed) return -1;
    if (n > (size_t)-1 / 2 - b->len) { b->failed = 1; return -1; }
    if (b->len + n + 1 <= b->cap) return 0;
    size_t cap = b->cap ? b->cap : 128;
    while (cap < b->len + n + 1) cap *= 2;
    char *s = frep_realloc(b->s, cap);
    if (!s) { b->failed = 1; return -1; }
    b->s = s;
    b->cap = cap;
    return 0;
}

void buf_put(frep_buf *b, const char *s, size_t n)
{
    if (buf_reserve(b, n) != 0) return;
    memcpy(b->s + b->len, s, n);
    b->len += n;
    b->s[b->len] = '\0';
}

void buf_puts(frep_buf *b, const char *s) { buf_put(b, s, strlen(s)); }

void buf_putc(frep_buf *b, char c) { buf_put(b, &c, 1); }

void buf_printf(frep_buf *b, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0) { b->failed = 1; return; }
    if (buf_reserve(b, (size_t)n) != 0) return;
    va_start(ap, fmt);
    vsnprintf(b->s + b->len, (size_t)n + 1, fmt, ap);
    va_end(ap);
    b->len += (size_t)n;
}

char *buf_finish(frep_buf *b, size_t *len)
{
    if (!b->failed && !b->s) buf_put(b, "", 0);
    if (b->failed) {
        buf_free(b);
        return NULL;
    }
    char *s = b->s;
    if (len) *len = b->len;
    b->s = NULL;
    b->len = b->cap = 0;
    return s;
}

void buf_free(frep_buf *b)
{
    frep_free(b->s);
    b->s = NULL;
    b->len = b->cap = 0;
}
