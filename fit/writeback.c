/* writeback.c - in-place write-back of fitted values into a template's text (see
 * writeback.h): literal spans are replaced back to front, then the `-- @box` and note
 * lines are refreshed.  Pure text processing; cli/cmd_fit.c writes the result atomically.
 */
#include "alloc.h"
#include "buf.h"
#include "writeback.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void fit_format_number(char buf[FIT_NUMBER_MAX], double v, double lo, double hi)
{
    snprintf(buf, FIT_NUMBER_MAX, "%.10g", v);
    double back = strtod(buf, NULL);
    if (back < lo || back > hi) snprintf(buf, FIT_NUMBER_MAX, "%.17g", v);
}

static int cmp_edit(const void *a, const void *b)
{
    const fit_edit *x = a, *y = b;
    return x->off < y->off ? -1 : x->off > y->off;
}

/* Start of the line after position i (or len). */
static size_t next_line(const char *s, size_t len, size_t i)
{
    while (i < len && s[i] != '\n') i++;
    return i < len ? i + 1 : len;
}

static size_t skip_blank(const char *s, size_t len, size_t i)
{
    while (i < len && (s[i] == ' ' || s[i] == '\t')) i++;
    return i;
}

/* Does the line at i start (after blanks) with `--`, blanks, then `word`? */
static int line_is(const char *s, size_t len, size_t i, const char *word)
{
    i = skip_blank(s, len, i);
    if (i + 2 > len || s[i] != '-' || s[i + 1] != '-') return 0;
    i = skip_blank(s, len, i + 2);
    size_t w = strlen(word);
    return i + w <= len && memcmp(s + i, word, w) == 0;
}

/* The edits sorted by position, or NULL when a span is invalid (empty, past the end of
 * the text, overlapping another) or memory runs out. Free with frep_free. */
static fit_edit *sorted_edits(const fit_edit *edits, size_t n, size_t len)
{
    fit_edit *e = frep_malloc((n ? n : 1) * sizeof *e);
    if (e == NULL) return NULL;
    if (n) memcpy(e, edits, n * sizeof *e);
    if (n > 1) qsort(e, n, sizeof *e, cmp_edit);
    for (size_t k = 0; k < n; k++) {
        if (e[k].off >= e[k].end || e[k].end > len || (k > 0 && e[k].off < e[k - 1].end)) {
            frep_free(e);
            return NULL;
        }
    }
    return e;
}

/* Pass 1: src with each edit's span replaced by its formatted value (edits sorted). */
static char *apply_edits(const char *src, size_t len, const fit_edit *e, size_t n,
                         size_t *outlen)
{
    frep_buf a = FREP_BUF_INIT;
    size_t pos = 0;
    for (size_t k = 0; k < n; k++) {
        char num[FIT_NUMBER_MAX];
        fit_format_number(num, e[k].value, e[k].lo, e[k].hi);
        buf_put(&a, src + pos, e[k].off - pos);
        buf_puts(&a, num);
        pos = e[k].end;
    }
    buf_put(&a, src + pos, len - pos);
    return buf_finish(&a, outlen);
}

/* Room for "-- @box" and six numbers of %.6g with their blanks. */
#define FIT_BOX_LINE_MAX (7 * FIT_NUMBER_MAX + 16)

/* The pragma line `-- @box x0 y0 z0 x1 y1 z1` (no newline) into line. */
static void format_box_line(char line[FIT_BOX_LINE_MAX], const double *box)
{
    size_t m = (size_t)snprintf(line, FIT_BOX_LINE_MAX, "-- @box");
    for (int k = 0; k < 6; k++) {
        char num[FIT_NUMBER_MAX];
        snprintf(num, sizeof num, "%.6g", box[k]);
        m += (size_t)snprintf(line + m, FIT_BOX_LINE_MAX - m, " %s", num);
    }
}

/* Start of the first line that is neither blank nor a comment (len when there is
 * none): where the box line goes when the template has none before its code. */
static size_t first_code_line(const char *s, size_t len)
{
    for (size_t i = 0; i < len; i = next_line(s, len, i)) {
        size_t j = skip_blank(s, len, i);
        int blank = j >= len || s[j] == '\n' || s[j] == '\r';
        int comment = j + 1 < len && s[j] == '-' && s[j + 1] == '-';
        if (!blank && !comment) return i;
    }
    return len;
}

/* Bytes of the note that identify an old note line to replace: "-- fitted: -" names
 * the kind of note, the values after it change from fit to fit. An annotation note
 * ("-- @params 1, 2") is identified by its word and the blank after it. */
#define FIT_NOTE_KEY 12

/* Pass 2: the text of pass 1 copied line by line with the box and note lines put in. */
typedef struct wb_lines {
    const char *s;
    size_t len;
    const char *boxline;    /* NULL: the box is left alone */
    const char *note;       /* NULL: no note */
    size_t notekey;         /* a line starting with this many bytes of note is the old note */
    int found_box, placed_note;
    frep_buf out;
} wb_lines;

/* The note and its newline, unless it is placed already. */
static void put_note(wb_lines *w)
{
    if (w->note == NULL || w->placed_note) return;
    buf_puts(&w->out, w->note);
    buf_putc(&w->out, '\n');
    w->placed_note = 1;
}

/* The box line ended by eol, then the note right after it. */
static void put_box(wb_lines *w, const char *eol, size_t eollen)
{
    buf_puts(&w->out, w->boxline);
    buf_put(&w->out, eol, eollen);
    w->found_box = 1;
    put_note(w);
}

/* A newline unless the output is empty or ends with one. */
static void end_line(wb_lines *w)
{
    if (w->out.len > 0 && w->out.s[w->out.len - 1] != '\n') buf_putc(&w->out, '\n');
}

/* Is there an `-- @box` line at or after i? */
static int box_line_from(const char *s, size_t len, size_t i)
{
    for (; i < len; i = next_line(s, len, i))
        if (line_is(s, len, i, "@box")) return 1;
    return 0;
}

/* Copy the lines: the first `-- @box` line is replaced by ours (its line ending kept),
 * or ours goes before the first code line when no box line comes at all; an old note
 * line is dropped (the note follows the box line); box and note are appended at the end
 * when they found no place. */
static void rewrite_lines(wb_lines *w, size_t insert_at)
{
    const char *s = w->s;
    const size_t len = w->len;
    for (size_t i = 0; i < len;) {
        size_t nl = next_line(s, len, i);
        int is_box = w->boxline != NULL && line_is(s, len, i, "@box");
        if (w->boxline != NULL && !w->found_box && i == insert_at && !is_box &&
            !box_line_from(s, len, i))
            put_box(w, "\n", 1);
        if (w->note != NULL && nl - i >= w->notekey && memcmp(s + i, w->note, w->notekey) == 0) {
            i = nl;             /* the old note: rewritten next to the box */
            continue;
        }
        if (is_box && !w->found_box) {
            size_t eol = nl;
            while (eol > i && (s[eol - 1] == '\n' || s[eol - 1] == '\r')) eol--;
            if (nl == eol) put_box(w, "\n", 1);
            else put_box(w, s + eol, nl - eol);
            i = nl;
            continue;
        }
        buf_put(&w->out, s + i, nl - i);
        i = nl;
    }
    if (w->boxline != NULL && !w->found_box) {
        end_line(w);
        put_box(w, "\n", 1);
    }
    if (w->note != NULL && !w->placed_note) {
        end_line(w);
        put_note(w);
    }
}

char *fit_writeback(const char *src, size_t len, const fit_edit *edits, size_t n,
                    const double *box, const char *note, size_t *outlen)
{
    fit_edit *e = sorted_edits(edits, n, len);
    if (e == NULL) return NULL;
    size_t tlen = 0;
    char *text = apply_edits(src, len, e, n, &tlen);
    frep_free(e);
    if (text == NULL || (box == NULL && note == NULL)) {
        if (text != NULL) *outlen = tlen;
        return text;
    }
    char boxline[FIT_BOX_LINE_MAX];
    if (box != NULL) format_box_line(boxline, box);
    wb_lines w = {text, tlen, box != NULL ? boxline : NULL, note, 0, 0, 0, FREP_BUF_INIT};
    w.notekey = note != NULL ? strlen(note) : 0;
    if (note != NULL && strncmp(note, "-- @", 4) == 0)
        w.notekey = 4 + strcspn(note + 4, " ") + (note[4 + strcspn(note + 4, " ")] == ' ');
    else if (w.notekey > FIT_NOTE_KEY)
        w.notekey = FIT_NOTE_KEY;
    rewrite_lines(&w, first_code_line(text, tlen));
    frep_free(text);
    return buf_finish(&w.out, outlen);
}
