/* png.h - the PNG encoder of `frep render` (8-bit RGB, each row filtered with the PNG
 * filter that suits it best, deflated by zlib, CRC-32).
 */
#ifndef FREP_PNG_H
#define FREP_PNG_H

#include <stdint.h>
#include <stdio.h>

/* Largest image side accepted: keeps width * height * 3 well inside size_t and the
 * file below 4 GiB (PNG chunk lengths are 31-bit). */
#define PNG_MAX_SIDE 16384

/* Write a w x h RGB image (rgb: 3 bytes per pixel, rows top to bottom). Returns 0, or
 * -1 on a write error, a bad size or out of memory. */
int png_write_rgb(FILE *f, const uint8_t *rgb, int w, int h);

/* CRC-32 (ISO 3309, as used by PNG) of n bytes, continuing from crc (start with 0). */
uint32_t png_crc32(uint32_t crc, const uint8_t *p, size_t n);

#endif
