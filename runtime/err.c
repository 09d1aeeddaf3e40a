/* err.c - the library's error struct (runtime/err.h). */
#include "err.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

void frep_error_init(frep_error *e)
{
    if (!e) return;
    e->code = FREP_EOK;
    e->line = 0;
    e->col = 0;
    e->msg[0] = '\0';
}

/* Control bytes of the data echoed in a message (a NUL-free binary file read as text)
 * would drive the terminal: each becomes "\xNN" (the message is cut at its end if
 * that makes it longer than it can hold). */
static void escape_controls(char *msg, size_t cap)
{
    char tmp[FREP_ERROR_MSG_MAX];
    size_t o = 0;
    int any = 0;
    for (const unsigned char *p = (const unsigned char *)msg; *p; p++)
        any |= *p < 0x20 || *p == 0x7f;
    if (!any) return;
    for (const unsigned char *p = (const unsigned char *)msg; *p && o + 5 < sizeof tmp; p++) {
        if (*p < 0x20 || *p == 0x7f) o += (size_t)snprintf(tmp + o, sizeof tmp - o, "\\x%02x", *p);
        else tmp[o++] = (char)*p;
    }
    tmp[o] = '\0';
    snprintf(msg, cap, "%s", tmp);
}

static int error_vset(frep_error *e, frep_error_code code, const char *path, long line,
                      int col, const char *fmt, va_list ap)
{
    if (!e || e->code != FREP_EOK) return -1;
    size_t n = 0;
    int k = 0;
    if (path && line > 0 && col > 0) k = snprintf(e->msg, sizeof e->msg, "%s:%ld:%d: ", path, line, col);
    else if (path && line > 0) k = snprintf(e->msg, sizeof e->msg, "%s:%ld: ", path, line);
    else if (path) k = snprintf(e->msg, sizeof e->msg, "%s: ", path);
    if (k > 0) n = (size_t)k < sizeof e->msg ? (size_t)k : sizeof e->msg - 1;
    if (vsnprintf(e->msg + n, sizeof e->msg - n, fmt, ap) < 0) e->msg[n] = '\0';
    escape_controls(e->msg, sizeof e->msg);
    e->code = code;
    e->line = line;
    e->col = col;
    return -1;
}

int frep_error_set(frep_error *e, frep_error_code code, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    error_vset(e, code, NULL, 0, 0, fmt, ap);
    va_end(ap);
    return -1;
}

int frep_error_at(frep_error *e, frep_error_code code, const char *path, long line, int col,
                  const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    error_vset(e, code, path, line, col, fmt, ap);
    va_end(ap);
    return -1;
}

int frep_error_nomem(frep_error *e) { return frep_error_set(e, FREP_ENOMEM, "out of memory"); }

int frep_error_prefix(frep_error *e, const char *fmt, ...)
{
    if (!e || e->code == FREP_EOK) return -1;
    char old[FREP_ERROR_MSG_MAX];
    memcpy(old, e->msg, sizeof old);
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(e->msg, sizeof e->msg, fmt, ap);
    va_end(ap);
    size_t n = k < 0 ? 0 : (size_t)k < sizeof e->msg ? (size_t)k : sizeof e->msg - 1;
    snprintf(e->msg + n, sizeof e->msg - n, "%s", old);
    return -1;
}
