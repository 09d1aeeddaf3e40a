/* diag.c - diagnostics of a compile session: diag_report hands a positioned message
 * to the user's callback (the library never prints), frep_diag_format renders one
 * GNU-style with the source line and a caret span, as the frep command prints it.
 */
#include "alloc.h"
#include "ast.h"
#include "buf.h"

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

/* A UTF-8 continuation byte takes no column of its own. */
static int is_cont(unsigned char c) { return (c & 0xC0) == 0x80; }

char *frep_diag_format(const frep_diag *d, const char *source, size_t source_len)
{
    frep_buf b = FREP_BUF_INIT;
    const char *sev = d->severity == FREP_ERROR ? "error"
                    : d->severity == FREP_WARNING ? "warning" : "note";
    if (d->file) {
        buf_puts(&b, d->file);
        buf_puts(&b, ":");
    }
    if (d->line) buf_printf(&b, "%u:%u:", (unsigned)d->line, (unsigned)d->col);
    if (b.len) buf_puts(&b, " ");
    buf_puts(&b, sev);
    buf_puts(&b, ": ");
    buf_puts(&b, d->message ? d->message : "");
    buf_puts(&b, "\n");

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
            buf_put(&b, source + start, text_end - start);
            buf_puts(&b, "\n");
            /* Caret line: reproduce tabs so the caret lines up under any tab width. */
            size_t col = d->col ? d->col : 1;
            for (size_t k = start; k < text_end && k < start + col - 1; k++) {
                unsigned char c = (unsigned char)source[k];
                if (c == '\t') buf_puts(&b, "\t");
                else if (!is_cont(c)) buf_puts(&b, " ");
            }
            /* A column past the end of the line (end of file, missing ';') gets its
             * caret right after the last character. */
            for (size_t k = text_end; k < start + col - 1; k++) buf_puts(&b, " ");
            buf_puts(&b, "^");
            size_t span_end = start + col - 1 + (d->len ? d->len : 1);
            for (size_t k = start + col; k < span_end && k < text_end; k++)
                if (!is_cont((unsigned char)source[k])) buf_puts(&b, "~");
            buf_puts(&b, "\n");
        }
    }
    return buf_finish(&b, NULL);
}
