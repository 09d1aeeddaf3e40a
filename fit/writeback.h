/* writeback.h - writes fitted parameter values back into the template text: each named
 * parameter's number literal is replaced in place (by its byte span from the compiler),
 * so comments, layout, names and bounds stay as the user wrote them; an `-- @box` pragma
 * line is added or refreshed.  The last step of `frep fit` (cli/cmd_fit.c).
 */
#ifndef FREP_FIT_WRITEBACK_H
#define FREP_FIT_WRITEBACK_H

#include <stddef.h>
#include <stdint.h>

/* Replace the literal in src[off, end) by `value`. lo/hi: the parameter's bounds (the
 * printed value is kept inside them). */
typedef struct fit_edit {
    uint32_t off, end;
    double value, lo, hi;
} fit_edit;

/* Longest text fit_format_number writes, NUL included ("-1.2345678901234567e-308"). */
#define FIT_NUMBER_MAX 32

/* The shortest of %.10g and %.17g that reads back inside [lo, hi] (10 significant
 * digits are far below fitting accuracy and keep the template readable). */
void fit_format_number(char buf[FIT_NUMBER_MAX], double v, double lo, double hi);

/* New text of the template: src with the edits applied (any order; spans must not
 * overlap and must lie inside src), the `-- @box` line replaced or, if there is none,
 * inserted before the first line that is not a comment or blank (box may be NULL: no
 * box change), and `note` (a full comment line without newline, may be NULL) put right
 * after the box line, replacing an earlier line that starts with the same first 12
 * characters (for an annotation note `-- @word ...`: with `-- @word `). Returns a malloc'ed NUL-terminated string (frep_free()) and its length in
 * *outlen, or NULL when a span is invalid or memory runs out. */
char *fit_writeback(const char *src, size_t len, const fit_edit *edits, size_t n,
                    const double *box, const char *note, size_t *outlen);

#endif
