/* page.h - the page of `frep view`: one self-contained HTML file (the WebGL viewer of
 * view/viewer.html, compiled into the library, with the scene inlined) that opens from
 * disk without a server or network.  The scene is the mesh, the cloud with the
 * distances of view/distance.h, the model's text and parameters, compiler messages.
 */
#ifndef FREP_PAGE_H
#define FREP_PAGE_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "buf.h"
#include "err.h"
#include "frep.h"
#include "trimesh.h"

/* What the page shows: the public scene (runtime/frep.h), every pointer may be NULL. */
typedef frep_view_scene view_scene;

/* The viewer (view/viewer.html, generated into view_template.c by the build). */
extern const char view_template[];

/* Append the scene as one JSON object: arrays in base64, positions as little-endian
 * Uint16 fractions of their bounds ("lo", "hi"), distances as IEEE halves
 * (view_half), normals as Int8
 * (times 127), colours as Uint8 RGB, triangle corners as zigzag LEB128 varints of their
 * differences. */
void view_scene_json(frep_buf *b, const view_scene *s);

/* v as an IEEE half (binary16), rounded to nearest; +-infinity beyond 65504; a
 * non-zero value too small for a half is +-2^-24, keeping its sign. */
uint16_t view_half(double v);

/* The page: the template with the scene inlined; watch != 0 makes it ask the server
 * that sent it for new versions of the scene.  Returns the text (free with frep_free)
 * and its length, or NULL with *e set (out of memory). */
char *view_page(const view_scene *s, int watch, size_t *len, frep_error *e);

/* view_page() written to f.  Returns 0, or -1 with *e set (FREP_ENOMEM, FREP_EIO). */
int view_write_page(FILE *f, const view_scene *s, frep_error *e);

#endif
