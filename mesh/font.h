/* font.h - a 5x7 bitmap font for the legends of `frep render` (mesh/render.c): the
 * digits, the lower-case letters (upper case is drawn as lower case) and the
 * punctuation numbers and units need.  Unknown characters are drawn as blanks.
 */
#ifndef FREP_FONT_H
#define FREP_FONT_H

#include <stdint.h>

#define FONT_W 5        /* glyph width in pixels at scale 1 */
#define FONT_H 7        /* glyph height */
#define FONT_ADVANCE 6  /* glyph width plus spacing */

/* Width in pixels of s drawn at scale k. */
int font_width(const char *s, int k);
/* Draw s with its top-left corner at (x, y), each font pixel a k x k square of colour
 * col, clipped to the w x h RGB image. */
void font_draw(uint8_t *rgb, int w, int h, int x, int y, int k, const char *s,
               const uint8_t col[3]);

#endif
