/* ply.h — reader for PLY triangle meshes (the format of pbrt's "plymesh" shapes).
 *
 * Accepts ascii, binary_little_endian and binary_big_endian bodies, every PLY scalar type for
 * every property, list properties with any count and item types, and unknown elements or
 * properties (which are skipped). Gzip-compressed files are recognised and refused.
 *
 * Vertex properties used: x y z (required); nx ny nz (all three, optional); a texture
 * coordinate pair named u v, s t, texture_u texture_v or texture_s texture_t (optional, first
 * pair in the header wins). Face property used: the list vertex_indices (or vertex_index).
 * Other properties, such as pbrt's face_indices, are read past and ignored.
 */
#ifndef PN_SCENE_PLY_H
#define PN_SCENE_PLY_H

#include "core/error.h"

#include <stdint.h>

typedef struct pn_ply_mesh {
    uint32_t vertex_count, triangle_count;
    float *positions; /* 3 * vertex_count */
    float *normals;   /* 3 * vertex_count or NULL */
    float *uvs;       /* 2 * vertex_count or NULL */
    /* 3 * triangle_count; quads split into two triangles (0,1,2),(0,2,3); n-gons fanned */
    uint32_t *indices;
    uint32_t skipped_face_count; /* faces with fewer than 3 vertices, which were left out */
} pn_ply_mesh;

/* Reads the mesh at path into *mesh (which is overwritten; free it with pn_ply_mesh_free).
 *
 * A file that cannot be opened or read gives PN_ERROR_IO ("path: strerror"); anything wrong
 * with its contents gives PN_ERROR_BAD_INPUT ("path: what is wrong"). Contents are rejected for:
 * a malformed header, a body shorter than the header promises, a face index outside
 * [0, vertex_count), a negative list count, a non-finite position or texture coordinate, more
 * than 2^32 - 1 vertices or triangles. Faces with fewer than three vertices are skipped and
 * counted in skipped_face_count. Normals are returned normalised; if any vertex normal is zero
 * or not finite the whole mesh is returned without normals (normals == NULL), so that callers
 * fall back to geometric normals instead of interpolating a broken one.
 *
 * On failure *mesh is left zeroed (nothing to free, though freeing it is harmless). */
pn_status pn_ply_read(const char *path, pn_ply_mesh *mesh, pn_err *err);

/* Releases the arrays of a mesh filled by pn_ply_read and zeroes it. Accepts NULL. */
void pn_ply_mesh_free(pn_ply_mesh *mesh);

#endif
