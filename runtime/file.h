/* file.h - reading a whole file into memory, the one file reader of the library
 * (clouds, meshes and primitive lists are parsed from memory after it). Part of the
 * shared base; the command line (cli/) has its own reader for its inputs.
 */
#ifndef FREP_FILE_H
#define FREP_FILE_H

#include <stddef.h>
#include <stdint.h>

#include "err.h"

/* Largest file the library reads whole: 16 GiB, beyond any cloud or mesh it can hold
 * in memory (segmentation indexes points with 32 bits, and a point takes 24 bytes or
 * more); guards against a device or a runaway pipe. Half the address space on a
 * 32-bit build. */
#define FREP_FILE_MAX_BYTES \
    ((uint64_t)SIZE_MAX / 2 < ((uint64_t)1 << 34) ? SIZE_MAX / 2 : (size_t)((uint64_t)1 << 34))

/* flags of frep_file_read */
#define FREP_FILE_STDIN 1u   /* the path "-" reads standard input (left open) */

typedef struct frep_file {
    char *data;       /* the bytes with a NUL after them (frep_free); NULL after failure */
    size_t len;       /* bytes read, the NUL not counted */
    int open_failed;  /* after a failure: 1 when the file could not be opened at all */
} frep_file;

/* Read the file at path, at most max_bytes of it, into f. Returns 0, or -1 with e set
 * to the reason alone, for the caller to put into its own message: errno's text
 * (FREP_EIO: opening or reading failed, see f->open_failed), "out of memory"
 * (FREP_ENOMEM) or "larger than N bytes" (FREP_ELIMIT). */
int frep_file_read(frep_file *f, const char *path, size_t max_bytes, unsigned flags,
                   frep_error *e);

#endif
