/* shapes.c — turning pbrt shapes into world-space triangle meshes: transforming vertex data and
 * tessellating disks and cylinders. */
#include "scene/parser_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PN_PI_D 3.14159265358979323846

void pn_mesh_data_free(pn_mesh_data *d) {
    if (!d) return;
    free(d->positions);
    free(d->normals);
    free(d->uvs);
    free(d->indices);
    memset(d, 0, sizeof *d);
}

static bool is_identity(const mat4 *M) {
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++)
            if (M->m[r][c] != (r == c ? 1.0 : 0.0)) return false;
    return true;
}

pn_status pn_mesh_from_data(pn_mesh_data *d, const mat4 *M, bool reverse_orientation, pn_mesh *mesh,
                            const pn_srcloc *loc, bool *normals_dropped, pn_err *err) {
    *normals_dropped = false;
    bool identity = is_identity(M);
    float *P = d->positions;
    for (uint32_t i = 0; i < d->vertex_count; i++) {
        vec3 p = v3(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
        if (!identity) p = mat4_apply_point(M, p);
        if (!v3_is_finite(p)) {
            pn_mesh_data_free(d);
            return pn_loc_error(loc, PN_ERROR_BAD_INPUT, err,
                                "vertex %u has a non-finite position (after the transform)", i);
        }
        P[3 * i] = p.x;
        P[3 * i + 1] = p.y;
        P[3 * i + 2] = p.z;
    }
    if (d->normals) {
        mat4 inv;
        if (!identity && !mat4_inverse(*M, &inv)) {
            pn_mesh_data_free(d);
            return pn_loc_error(loc, PN_ERROR_BAD_INPUT, err,
                                "the current transform is singular, so the normals \"N\" cannot be transformed");
        }
        float *N = d->normals;
        float sign = reverse_orientation ? -1.0f : 1.0f;
        for (uint32_t i = 0; i < d->vertex_count; i++) {
            vec3 n = v3(N[3 * i], N[3 * i + 1], N[3 * i + 2]);
            if (!identity) n = mat4_apply_normal(&inv, n);
            float len = v3_length(n);
            if (!(len > 0.0f) || !isfinite(len)) {
                free(d->normals);
                d->normals = NULL;
                *normals_dropped = true;
                break;
            }
            n = v3_scale(n, sign / len);
            N[3 * i] = n.x;
            N[3 * i + 1] = n.y;
            N[3 * i + 2] = n.z;
        }
    }
    mesh->vertex_count = d->vertex_count;
    mesh->triangle_count = d->triangle_count;
    mesh->positions = d->positions;
    mesh->normals = d->normals;
    mesh->uvs = d->uvs;
    mesh->indices = d->indices;
    memset(d, 0, sizeof *d);
    return PN_OK;
}

static inline vec3 vertex(const float *P, uint32_t i) { return v3(P[3 * i], P[3 * i + 1], P[3 * i + 2]); }

double pn_mesh_area(const pn_mesh *mesh) {
    double sum = 0.0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *ix = &mesh->indices[3 * t];
        vec3 p0 = vertex(mesh->positions, ix[0]);
        vec3 c = v3_cross(v3_sub(vertex(mesh->positions, ix[1]), p0), v3_sub(vertex(mesh->positions, ix[2]), p0));
        sum += 0.5 * (double)v3_length(c);
    }
    return sum;
}

uint32_t pn_mesh_degenerate_count(const pn_mesh *mesh) {
    uint32_t n = 0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *ix = &mesh->indices[3 * t];
        if (ix[0] == ix[1] || ix[1] == ix[2] || ix[0] == ix[2]) {
            n++;
            continue;
        }
        vec3 p0 = vertex(mesh->positions, ix[0]);
        vec3 c = v3_cross(v3_sub(vertex(mesh->positions, ix[1]), p0), v3_sub(vertex(mesh->positions, ix[2]), p0));
        if (v3_length2(c) == 0.0f) n++;
    }
    return n;
}

void pn_mesh_bounds(const pn_mesh *mesh, vec3 *lo, vec3 *hi) {
    vec3 a = v3(INFINITY, INFINITY, INFINITY), b = v3(-INFINITY, -INFINITY, -INFINITY);
    for (uint32_t i = 0; i < mesh->vertex_count; i++) {
        vec3 p = vertex(mesh->positions, i);
        a = v3_min(a, p);
        b = v3_max(b, p);
    }
    *lo = a;
    *hi = b;
}

static pn_status alloc_data(pn_mesh_data *out, uint32_t nv, uint32_t nt, bool normals, bool uvs, pn_err *err) {
    memset(out, 0, sizeof *out);
    out->vertex_count = nv;
    out->triangle_count = nt;
    out->positions = malloc((size_t)nv * 3 * sizeof(float));
    out->indices = malloc((size_t)nt * 3 * sizeof(uint32_t));
    if (normals) out->normals = malloc((size_t)nv * 3 * sizeof(float));
    if (uvs) out->uvs = malloc((size_t)nv * 2 * sizeof(float));
    if (!out->positions || !out->indices || (normals && !out->normals) || (uvs && !out->uvs)) {
        pn_mesh_data_free(out);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory tessellating a shape");
    }
    return PN_OK;
}

static void put_tri(uint32_t *ix, uint32_t a, uint32_t b, uint32_t c, bool reverse) {
    ix[0] = a;
    ix[1] = reverse ? c : b;
    ix[2] = reverse ? b : c;
}

pn_status pn_tessellate_disk(double height, double radius, double inner_radius, double phi_max_deg,
                             int segments, bool reverse_winding, pn_mesh_data *out, pn_err *err) {
    double phi_max = phi_max_deg * (PN_PI_D / 180.0);
    bool full = phi_max_deg >= 360.0;
    uint32_t ring = (uint32_t)segments + (full ? 0u : 1u); /* vertices per ring */
    bool annulus = inner_radius > 0.0;
    uint32_t nv = annulus ? 2 * ring : ring + 1;
    uint32_t nt = (uint32_t)segments * (annulus ? 2u : 1u);
    pn_status st = alloc_data(out, nv, nt, false, true, err);
    if (st != PN_OK) return st;
    float *P = out->positions, *UV = out->uvs;
    double span = radius - inner_radius;
    for (uint32_t i = 0; i < ring; i++) {
        double phi = phi_max * (double)i / (double)segments;
        double c = cos(phi), s = sin(phi);
        P[3 * i] = (float)(radius * c);
        P[3 * i + 1] = (float)(radius * s);
        P[3 * i + 2] = (float)height;
        UV[2 * i] = (float)(phi / phi_max);
        UV[2 * i + 1] = 0.0f;
        if (annulus) {
            uint32_t j = ring + i;
            P[3 * j] = (float)(inner_radius * c);
            P[3 * j + 1] = (float)(inner_radius * s);
            P[3 * j + 2] = (float)height;
            UV[2 * j] = (float)(phi / phi_max);
            UV[2 * j + 1] = span > 0.0 ? 1.0f : 0.0f;
        }
    }
    if (!annulus) {
        uint32_t c = ring;
        P[3 * c] = 0.0f;
        P[3 * c + 1] = 0.0f;
        P[3 * c + 2] = (float)height;
        UV[2 * c] = 0.0f;
        UV[2 * c + 1] = 1.0f;
    }
    uint32_t *ix = out->indices;
    for (uint32_t i = 0; i < (uint32_t)segments; i++) {
        uint32_t o0 = i, o1 = (i + 1) % ring;
        if (!full) o1 = i + 1;
        if (!annulus) {
            put_tri(ix, ring, o0, o1, reverse_winding);
            ix += 3;
        } else {
            uint32_t i0 = ring + o0, i1 = ring + o1;
            put_tri(ix, i0, o0, o1, reverse_winding);
            put_tri(ix + 3, i0, o1, i1, reverse_winding);
            ix += 6;
        }
    }
    return PN_OK;
}

pn_status pn_tessellate_cylinder(double radius, double zmin, double zmax, double phi_max_deg,
                                 int segments, bool reverse_winding, pn_mesh_data *out, pn_err *err) {
    double phi_max = phi_max_deg * (PN_PI_D / 180.0);
    uint32_t ring = (uint32_t)segments + 1; /* the seam is duplicated for the uvs */
    pn_status st = alloc_data(out, 2 * ring, 2 * (uint32_t)segments, true, true, err);
    if (st != PN_OK) return st;
    float *P = out->positions, *N = out->normals, *UV = out->uvs;
    for (uint32_t i = 0; i < ring; i++) {
        double phi = phi_max * (double)i / (double)segments;
        double c = cos(phi), s = sin(phi);
        for (uint32_t k = 0; k < 2; k++) {
            uint32_t j = k * ring + i;
            P[3 * j] = (float)(radius * c);
            P[3 * j + 1] = (float)(radius * s);
            P[3 * j + 2] = (float)(k ? zmax : zmin);
            N[3 * j] = (float)c;
            N[3 * j + 1] = (float)s;
            N[3 * j + 2] = 0.0f;
            UV[2 * j] = (float)(phi / phi_max);
            UV[2 * j + 1] = (float)k;
        }
    }
    uint32_t *ix = out->indices;
    for (uint32_t i = 0; i < (uint32_t)segments; i++) {
        uint32_t b0 = i, b1 = i + 1, t0 = ring + i, t1 = ring + i + 1;
        put_tri(ix, b0, b1, t1, reverse_winding);
        put_tri(ix + 3, b0, t1, t0, reverse_winding);
        ix += 6;
    }
    return PN_OK;
}

pn_status pn_loop_subdivide(pn_mesh_data *d, int levels, pn_err *err) {
    (void)d;
    (void)levels;
    (void)err;
    return PN_OK;
}
