/* file.c - the whole-file reader of the shared base (runtime/file.h). */
#include "file.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

#include "alloc.h"

/* First buffer size; it doubles as the file grows (a few reallocations for any file). */
#define FILE_FIRST_CHUNK ((size_t)1 << 16)

/* Grow f->data to hold *cap bytes and a NUL, doubling up to max_bytes; -1 when out
 * of memory. */
static int grow(frep_file *f, size_t *cap, size_t max_bytes)
{
    size_t ncap = *cap == 0 ? FILE_FIRST_CHUNK : *cap > max_bytes / 2 ? max_bytes : 2 * *cap;
    if (ncap > max_bytes) ncap = max_bytes;
    char *nb = frep_realloc(f->data, ncap + 1);
    if (!nb) return -1;
    f->data = nb;
    *cap = ncap;
    return 0;
}

/* A regular file's size when fp can tell it (0 otherwise: a pipe, a terminal). */
static size_t known_size(FILE *fp)
{
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size <= 0) return 0;
    return (size_t)st.st_size;
}

/* Read all of fp into f; 0, or -1 with e set.  A regular file's buffer is sized once
 * and its pages faulted in one call (frep_prefault): growing it by doubling copied
 * it and faulted each page on first write, about 12 us a page on the VMs frep is
 * measured on. */
static int read_all(frep_file *f, FILE *fp, size_t max_bytes, frep_error *e)
{
    size_t cap = 0, size = known_size(fp);
    if (size > 0) {
        /* one byte more than the file: the first fread then ends short, at its end */
        cap = size < max_bytes ? size + 1 : max_bytes;
        if (!(f->data = frep_malloc(cap + 1))) return frep_error_nomem(e);
        frep_prefault(f->data, cap + 1);
    }
    for (;;) {
        if (f->len == cap) {
            if (cap == max_bytes) {
                if (getc(fp) == EOF) break; /* exactly max_bytes long */
                return frep_error_set(e, FREP_ELIMIT, "larger than %zu bytes", max_bytes);
            }
            if (grow(f, &cap, max_bytes)) return frep_error_nomem(e);
        }
        size_t got = fread(f->data + f->len, 1, cap - f->len, fp);
        f->len += got;
        if (f->len < cap) break; /* end of file or an error */
    }
    if (ferror(fp)) return frep_error_set(e, FREP_EIO, "%s", strerror(errno));
    if (!f->data && grow(f, &cap, max_bytes)) return frep_error_nomem(e);
    f->data[f->len] = '\0';
    return 0;
}

int frep_file_read(frep_file *f, const char *path, size_t max_bytes, unsigned flags,
                   frep_error *e)
{
    memset(f, 0, sizeof *f);
    int is_stdin = (flags & FREP_FILE_STDIN) && strcmp(path, "-") == 0;
    FILE *fp = is_stdin ? stdin : fopen(path, "rb");
    if (!fp) {
        f->open_failed = 1;
        return frep_error_set(e, FREP_EIO, "%s", strerror(errno));
    }
    int rc = read_all(f, fp, max_bytes, e);
    if (!is_stdin) fclose(fp);
    if (rc) {
        frep_free(f->data);
        f->data = NULL;
        f->len = 0;
    }
    return rc;
}
