/* parser_internal.h — helpers shared by the scene parser's files (parser.c, params.c, shapes.c):
 * growable arrays and the mesh construction / tessellation routines of shapes.c.
 */
#ifndef PN_SCENE_PARSER_INTERNAL_H
#define PN_SCENE_PARSER_INTERNAL_H

#include "scene/scene.h"
#include "scene/tokenizer.h"

#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>

/* Makes room for one more element in an array that only ever grows by appending one element at
 * a time: its capacity is implied by its count (max(4, next power of two)), so no capacity field
 * is needed. Returns false (array unchanged) when memory runs out. */
static inline bool pn_grow_for_append(void **array, int count, size_t elem_size) {
    size_t new_cap;
    if (count == 0)
        new_cap = 4;
    else if (count >= 4 && (count & (count - 1)) == 0)
        new_cap = (size_t)count * 2;
    else
        return true;
    if (count > 0x3fffffff) return false;
    void *p = realloc(*array, new_cap * elem_size);
    if (!p) return false;
    *array = p;
    return true;
}

/* ---- shapes.c ---------------------------------------------------------------------------- */

/* Object-space mesh data before it becomes a pn_mesh: arrays are owned (malloc'd) and handed
 * over to the pn_mesh on success. */
typedef struct pn_mesh_data {
    uint32_t vertex_count, triangle_count;
    float *positions; /* 3 * vertex_count */
    float *normals;   /* 3 * vertex_count or NULL */
    float *uvs;       /* 2 * vertex_count or NULL */
    uint32_t *indices;
} pn_mesh_data;

void pn_mesh_data_free(pn_mesh_data *d);

/* Moves the data into *mesh (positions transformed by M, normals by its inverse transpose and
 * normalised, flipped when reverse_orientation as pbrt does for shading normals). Sets
 * vertex/triangle counts and arrays only; the caller fills the other fields. Fails with
 * PN_ERROR_BAD_INPUT at `loc` for a singular transform (when normals need it) or non-finite
 * results. `*normals_dropped` is set when some normal was degenerate and the normals were
 * dropped. On failure the data is freed. */
pn_status pn_mesh_from_data(pn_mesh_data *d, const mat4 *M, bool reverse_orientation, pn_mesh *mesh,
                            const pn_srcloc *loc, bool *normals_dropped, pn_err *err);

/* Sum of triangle areas. */
double pn_mesh_area(const pn_mesh *mesh);
/* Number of triangles with zero area. */
uint32_t pn_mesh_degenerate_count(const pn_mesh *mesh);
/* Bounds of the positions (lo > hi when empty). */
void pn_mesh_bounds(const pn_mesh *mesh, vec3 *lo, vec3 *hi);

/* Tessellates pbrt's disk (object space: z = height, radius, inner radius, phi_max in degrees)
 * with `segments` around. Triangles wind counter-clockwise seen from +z, or clockwise when
 * `reverse_winding`. */
pn_status pn_tessellate_disk(double height, double radius, double inner_radius, double phi_max_deg, int segments,
                             bool reverse_winding, pn_mesh_data *out, pn_err *err);

/* Tessellates pbrt's cylinder (object space: z axis, radius, z from zmin to zmax, phi_max) with
 * `segments` around; triangles face outwards (inwards when reverse_winding). */
pn_status pn_tessellate_cylinder(double radius, double zmin, double zmax, double phi_max_deg, int segments,
                                 bool reverse_winding, pn_mesh_data *out, pn_err *err);

/* Loop subdivision (Loop 1987) of a closed or open triangle mesh, `levels` times; replaces the
 * data. Boundary vertices and edges use the usual boundary rules. Normals/uvs are dropped. */
pn_status pn_loop_subdivide(pn_mesh_data *d, int levels, pn_err *err);

#endif
