/* err.h - the one error convention of libfrep outside the compiler (which reports
 * through frep_diag_fn) and the evaluators (frep_runtime_error).
 *
 * A function that can fail returns 0 / -1 (or a pointer / NULL) and, on failure, fills
 * the caller's frep_error: what kind of failure, where (a data file's path and line,
 * a model's line and column) and a message a person can act on. The message lives in
 * the struct, so reporting needs no allocation and "out of memory" is reported as
 * such. The first error set wins: later calls keep it (the root cause), so a cleanup
 * path may call frep_error_set without checking. No value is ever an error in band.
 */
#ifndef FREP_ERR_H
#define FREP_ERR_H

#include <stddef.h>

#define FREP_ERROR_MSG_MAX 512   /* the message with its position: longer ones are cut */

typedef enum frep_error_code {
    FREP_EOK = 0,      /* no error */
    FREP_ENOMEM,       /* an allocation failed */
    FREP_EINPUT,       /* bad data or argument: the message says which and where */
    FREP_EIO,          /* reading or writing a file failed (errno's reason in the message) */
    FREP_ELIMIT,       /* a named limit of frep was reached */
    FREP_ECANCEL,      /* the caller asked to stop */
    FREP_EINTERNAL     /* an invariant of frep failed: a bug */
} frep_error_code;

typedef struct frep_error {
    frep_error_code code;
    long line;         /* 1-based line in the data or model file; 0: none */
    int col;           /* 1-based column; 0: none */
    char msg[FREP_ERROR_MSG_MAX];  /* "path:line: what" (the position as set), NUL-ended */
} frep_error;

/* An empty error (code FREP_EOK, empty message). */
void frep_error_init(frep_error *e);

/* Set e (if not NULL and not set yet) to code with a printf message. Returns -1, so
 * `return frep_error_set(e, FREP_EINPUT, "...");` fails in one line. */
int frep_error_set(frep_error *e, frep_error_code code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* The same with a position: the message becomes "path:line: what" (line > 0) or
 * "path:line:col: what" (col > 0 too), or "path: what" (line 0); path may be NULL. */
int frep_error_at(frep_error *e, frep_error_code code, const char *path, long line, int col,
                  const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 6, 7)))
#endif
    ;

/* "out of memory" (FREP_ENOMEM); returns -1. */
int frep_error_nomem(frep_error *e);

/* Put "prefix" before a message already set ("reading c.xyz: ..."); returns -1. */
int frep_error_prefix(frep_error *e, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;

#endif
