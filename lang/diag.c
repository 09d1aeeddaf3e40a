/* diag.c - diagnostics of a compile session: diag_report hands a positioned message
 * to the user's callback (the library never prints), frep_diag_format renders one
 * GNU-style with the source line and a caret span, as the frep command prints it.
 */
#include "alloc.h"
#include "ast.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Longest message kept; names are at most FREP_MAX_IDENT characters, and a message
 * quotes a few of them plus fixed text. Longer messages are cut, never overflowed. */
#define DIAG_MAX_MESSAGE 2048

/* Hand one message to the callback, counted by severity. */
static void diag_emit(diag_sink *d, frep_severity sev, ast_loc loc, uint32_t len,
                      const char *msg)
{
    if (sev == FREP_ERROR) d->errors++;
    else if (sev == FREP_WARNING) d->warnings++;
    if (!d->fn) return;
    frep_diag fd;
    fd.severity = sev;
    fd.file = d->file;
    fd.line = loc.line;
    fd.col = loc.line ? loc.col : 0;
    fd.len = loc.line ? (len ? len : 1) : 0;
    fd.message = msg;
    d->fn(d->user, &fd);
}

void diag_nomem(diag_sink *d)
{
    if (!d || d->nomem) return;
    d->nomem = 1;
    ast_loc none = { 0, 0, 0, 0 };
    diag_emit(d, FREP_ERROR, none, 0, "out of memory");
}

void diag_report(diag_sink *d, frep_severity sev, ast_loc loc, uint32_t len,
                 const char *fmt, ...)
{
    if (!d) return;
    if (d->A && d->A->failed) diag_nomem(d);
    if (d->nomem) {
        /* Counted (so the stages stop) but not shown: see diag_sink. */
        if (sev == FREP_ERROR) d->errors++;
        return;
    }
    char msg[DIAG_MAX_MESSAGE];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    diag_emit(d, sev, loc, len, msg);
}

/* Growable output string; `failed` once an allocation fails. */
typedef struct sbuf {
    char *s;
    size_t n, cap;
    int failed;
} sbuf;

static void sb_put(sbuf *b, const char *s, size_t n)
{
    if (b->failed) return;
    if (b->n + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 128;
        while (cap < b->n + n + 1) cap *= 2;
        char *p = frep_realloc(b->s, cap);
        if (!p) { b->failed = 1; return; }
        b->s = p;
        b->cap = cap;
    }
    memcpy(b->s + b->n, s, n);
    b->n += n;
    b->s[b->n] = '\0';
}

static void sb_puts(sbuf *b, const char *s) { sb_put(b, s, strlen(s)); }

static void sb_printf(sbuf *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
static void sb_printf(sbuf *b, const char *fmt, ...)
{
    char tmp[64];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    if (n > 0) sb_put(b, tmp, (size_t)n < sizeof tmp ? (size_t)n : sizeof tmp - 1);
}

/* A UTF-8 continuation byte takes no column of its own. */
static int is_cont(unsigned char c) { return (c & 0xC0) == 0x80; }

char *frep_diag_format(const frep_diag *d, const char *source, size_t source_len)
{
    sbuf b = { NULL, 0, 0, 0 };
    const char *sev = d->severity == FREP_ERROR ? "error"
                    : d->severity == FREP_WARNING ? "warning" : "note";
    if (d->file) {
        sb_puts(&b, d->file);
        sb_puts(&b, ":");
    }
    if (d->line) sb_printf(&b, "%u:%u:", (unsigned)d->line, (unsigned)d->col);
    if (b.n) sb_puts(&b, " ");
    sb_puts(&b, sev);
    sb_puts(&b, ": ");
    sb_puts(&b, d->message ? d->message : "");
    sb_puts(&b, "\n");

    if (source && d->line) {
        /* Find the line: positions are 1-based, lines end at '\n' (a '\r' before it
         * belongs to the line break). */
        size_t i = 0;
        for (uint32_t ln = 1; ln < d->line && i < source_len; i++)
            if (source[i] == '\n') ln++;
        size_t start = i, end = i;
        while (end < source_len && source[end] != '\n') end++;
        size_t text_end = end;
        if (text_end > start && source[text_end - 1] == '\r') text_end--;
        if (start < source_len || d->line == 1) {
            sb_put(&b, source + start, text_end - start);
            sb_puts(&b, "\n");
            /* Caret line: reproduce tabs so the caret lines up under any tab width. */
            size_t col = d->col ? d->col : 1;
            for (size_t k = start; k < text_end && k < start + col - 1; k++) {
                unsigned char c = (unsigned char)source[k];
                if (c == '\t') sb_puts(&b, "\t");
                else if (!is_cont(c)) sb_puts(&b, " ");
            }
            /* A column past the end of the line (end of file, missing ';') gets its
             * caret right after the last character. */
            for (size_t k = text_end; k < start + col - 1; k++) sb_puts(&b, " ");
            sb_puts(&b, "^");
            size_t span_end = start + col - 1 + (d->len ? d->len : 1);
            for (size_t k = start + col; k < span_end && k < text_end; k++)
                if (!is_cont((unsigned char)source[k])) sb_puts(&b, "~");
            sb_puts(&b, "\n");
        }
    }
    if (b.failed) {
        frep_free(b.s);
        return NULL;
    }
    return b.s;
}
