/* buf.h - the growable byte buffer of libfrep: the disassembler, diagnostics, frep
 * print, the fit write-back and the refit's model text build their strings in one.
 *
 * Appending never fails loudly: after a failed allocation the buffer is marked failed,
 * further appends do nothing, and buf_finish reports it once.
 */
#ifndef FREP_BUF_H
#define FREP_BUF_H

#include <stddef.h>

typedef struct frep_buf {
    char *s;         /* NUL-terminated when len > 0 and !failed; NULL before the first append */
    size_t len, cap;
    int failed;      /* an allocation failed: the contents are incomplete */
} frep_buf;

#define FREP_BUF_INIT {NULL, 0, 0, 0}

void buf_put(frep_buf *b, const char *s, size_t n);
void buf_puts(frep_buf *b, const char *s);
void buf_putc(frep_buf *b, char c);
void buf_printf(frep_buf *b, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
/* The string (free with frep_free) and its length in *len (may be NULL); an empty
 * buffer gives "". NULL when an append failed (the buffer is released). */
char *buf_finish(frep_buf *b, size_t *len);
/* Release without taking the string. */
void buf_free(frep_buf *b);

#endif
