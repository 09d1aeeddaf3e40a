/* meshio.h - triangle mesh files: write what mesh/mesh.c makes (STL binary and
 * ASCII, OBJ, PLY binary and ASCII, OFF, VRML 2.0) and read triangle meshes (OFF, OBJ, STL, PLY)
 * for `frep sample MESH`.  Writers take a FILE so the CLI can write atomically.
 */
#ifndef FREP_MESHIO_H
#define FREP_MESHIO_H

#include <stdint.h>
#include <stdio.h>

#include "err.h"
#include "trimesh.h"

typedef enum meshio_format {
    MESHIO_UNKNOWN = 0,
    MESHIO_STL,
    MESHIO_OBJ,
    MESHIO_PLY,
    MESHIO_OFF,
    MESHIO_WRL        /* VRML 2.0 (VRML97) IndexedFaceSet: written, not read */
} meshio_format;

/* VRML's diffuse colour of a mesh without vertex colours: HyperFun hfp's default face
 * colour (-cf 50,200,80). */
#define MESHIO_WRL_DEFAULT_RGB 50, 200, 80

/* Longest mesh the readers accept (vertices or faces): refuses absurd header counts
 * before allocating. */
#define MESHIO_MAX_ELEMENTS ((size_t)1 << 28)

/* Format from the file name's extension (case-insensitive); MESHIO_UNKNOWN if none. */
meshio_format meshio_format_for_path(const char *path);
const char *meshio_format_name(meshio_format f);

/* Write m in format fmt; ascii selects text STL / text PLY (OBJ, OFF and VRML are
 * always text). Returns 0, or -1 on a write error. */
int meshio_write(FILE *f, const frep_mesh *m, meshio_format fmt, int ascii);
/* The same with vertex colours rgb (3 bytes a vertex, mesh_colors(); NULL: none):
 * PLY gets uchar red, green, blue properties, VRML a Color node (colorPerVertex);
 * STL, OBJ and OFF have none to write (rgb is ignored). VRML without colours gets a
 * Material of MESHIO_WRL_DEFAULT_RGB. */
int meshio_write_colored(FILE *f, const frep_mesh *m, const uint8_t *rgb, meshio_format fmt,
                         int ascii);

/* Read a triangle mesh (polygons are split into fans). The format comes from the
 * extension, or the content for STL (ASCII or binary) and PLY (ascii, binary little
 * and big endian). Returns 0 and fills *m (free with mesh_free; m->n is NULL), or -1
 * with err (reset on entry; may be NULL) holding "path:line: what". */
int meshio_read(const char *path, frep_mesh *m, frep_error *err);
/* The same from memory; `name` names the data in messages, fmt may be MESHIO_UNKNOWN
 * (then guessed from the content). */
int meshio_parse(const char *name, const char *data, size_t len, meshio_format fmt,
                 frep_mesh *m, frep_error *err);

#endif
