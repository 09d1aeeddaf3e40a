/* writeback.c - in-place write-back of fitted values into a template's text (see
 * writeback.h): literal spans are replaced back to front, then the `-- @box` and note
 * lines are refreshed.  Pure text processing; cli/cmd_fit.c writes the result atomically.
 */
#include "alloc.h"
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

/* A growable byte buffer. */
typedef struct sbuf {
    char *p;
    size_t n, cap;
    int failed;
} sbuf;

static void sb_put(sbuf *b, const char *s, size_t n)
{
    if (b->failed) return;
    if (b->n + n + 1 > b->cap) {
        size_t cap = (b->n + n + 1) * 2;
        char *q = frep_realloc(b->p, cap);
        if (q == NULL) {
            b->failed = 1;
            return;
        }
        b->p = q, b->cap = cap;
    }
    memcpy(b->p + b->n, s, n);
    b->n += n;
    b->p[b->n] = '\0';
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

char *fit_writeback(const char *src, size_t len, const fit_edit *edits, size_t n,
                    const double *box, const char *note, size_t *outlen)
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
    /* Pass 1: the literals. */
    sbuf a = {0};
    size_t pos = 0;
    for (size_t k = 0; k < n; k++) {
        char num[FIT_NUMBER_MAX];
        fit_format_number(num, e[k].value, e[k].lo, e[k].hi);
        sb_put(&a, src + pos, e[k].off - pos);
        sb_put(&a, num, strlen(num));
        pos = e[k].end;
    }
    sb_put(&a, src + pos, len - pos);
    frep_free(e);
    if (a.failed || (a.p == NULL && (sb_put(&a, "", 0), a.failed))) {
        frep_free(a.p);
        return NULL;
    }
    if (box == NULL && note == NULL) {
        *outlen = a.n;
        return a.p;
    }

    /* Pass 2: the box and note lines. */
    char boxline[7 * FIT_NUMBER_MAX + 16] = "";
    if (box != NULL) {
        size_t m = (size_t)snprintf(boxline, sizeof boxline, "-- @box");
        for (int k = 0; k < 6; k++) {
            char num[FIT_NUMBER_MAX];
            snprintf(num, sizeof num, "%.6g", box[k]);
            m += (size_t)snprintf(boxline + m, sizeof boxline - m, " %s", num);
        }
    }
    size_t notekey = note != NULL ? strlen(note) : 0;
    if (notekey > 12) notekey = 12;
    const char *s = a.p;
    size_t sl = a.n, insert_at = sl;
    int found_box = 0, placed_note = 0;
    /* Where to insert when there is no @box line: the first code line. */
    for (size_t i = 0; i < sl; i = next_line(s, sl, i)) {
        size_t j = skip_blank(s, sl, i);
        int blank = j >= sl || s[j] == '\n' || s[j] == '\r';
        int comment = j + 1 < sl && s[j] == '-' && s[j + 1] == '-';
        if (!blank && !comment) {
            insert_at = i;
            break;
        }
    }
    sbuf b = {0};
    for (size_t i = 0; i < sl;) {
        size_t nl = next_line(s, sl, i);
        int is_box = box != NULL && line_is(s, sl, i, "@box");
        int is_note = note != NULL && nl - i >= notekey && memcmp(s + i, note, notekey) == 0;
        if (!found_box && box != NULL && i == insert_at && !is_box) {
            /* No @box line before the code: insert ours (and the note) here. */
            int later = 0;
            for (size_t k = i; k < sl; k = next_line(s, sl, k)) later |= line_is(s, sl, k, "@box");
            if (!later) {
                sb_put(&b, boxline, strlen(boxline));
                sb_put(&b, "\n", 1);
                found_box = 1;
                if (note != NULL && !placed_note) {
                    sb_put(&b, note, strlen(note));
                    sb_put(&b, "\n", 1);
                    placed_note = 1;
                }
            }
        }
        if (is_note) {                  /* dropped: rewritten next to the box */
            i = nl;
            continue;
        }
        if (is_box && !found_box) {
            size_t eol = nl;
            while (eol > i && (s[eol - 1] == '\n' || s[eol - 1] == '\r')) eol--;
            sb_put(&b, boxline, strlen(boxline));
            sb_put(&b, s + eol, nl - eol);
            if (nl == eol) sb_put(&b, "\n", 1);
            found_box = 1;
            if (note != NULL && !placed_note) {
                sb_put(&b, note, strlen(note));
                sb_put(&b, "\n", 1);
                placed_note = 1;
            }
            i = nl;
            continue;
        }
        sb_put(&b, s + i, nl - i);
        i = nl;
    }
    if (box != NULL && !found_box) {
        if (b.n > 0 && b.p[b.n - 1] != '\n') sb_put(&b, "\n", 1);
        sb_put(&b, boxline, strlen(boxline));
        sb_put(&b, "\n", 1);
    }
    if (note != NULL && !placed_note) {
        if (b.n > 0 && b.p[b.n - 1] != '\n') sb_put(&b, "\n", 1);
        sb_put(&b, note, strlen(note));
        sb_put(&b, "\n", 1);
    }
    frep_free(a.p);
    if (b.failed || b.p == NULL) {
        frep_free(b.p);
        return NULL;
    }
    *outlen = b.n;
    return b.p;
}
