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

static inline vec3 vertex(const float *P, uint32_t i) {
    return v3(P[3 * i], P[3 * i + 1], P[3 * i + 2]);
}

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

pn_status pn_tessellate_disk(double height, double radius, double inner_radius, double phi_max_deg, int segments,
                             bool reverse_winding, pn_mesh_data *out, pn_err *err) {
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

pn_status pn_tessellate_cylinder(double radius, double zmin, double zmax, double phi_max_deg, int segments,
                                 bool reverse_winding, pn_mesh_data *out, pn_err *err) {
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

/* ---- Loop subdivision -------------------------------------------------------------------- */

/* One half-edge of the input: the undirected edge's key and the corner it starts at. */
typedef struct pn_half_edge {
    uint64_t key;    /* (min vertex << 32) | max vertex */
    uint32_t corner; /* 3 * triangle + k: the edge runs from corner k to corner k+1 */
} pn_half_edge;

static int compare_half_edges(const void *a, const void *b) {
    const pn_half_edge *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->corner < y->corner ? -1 : (x->corner > y->corner);
}

/* Loop's weight for an interior vertex of valence n (3/16 for n = 3, else 3/(8n)). */
static double loop_beta(uint32_t n) {
    return n == 3 ? 3.0 / 16.0 : 3.0 / (8.0 * (double)n);
}

/* One level of Loop subdivision (Loop 1987, "Smooth Subdivision Surfaces Based on Triangles",
 * section 3.2): every triangle becomes four; old ("even") vertices move by the valence-weighted
 * mask, new ("odd") vertices on edges use 3/8 for the edge ends and 1/8 for the two opposite
 * vertices. Boundary (and non-manifold) edges use the cubic B-spline rules 1/2,1/2 and 1/8,3/4,1/8. */
static pn_status loop_level(uint32_t nv, uint32_t nt, const double *P, const uint32_t *ix, double **out_p,
                            uint32_t **out_ix, uint32_t *out_nv, uint32_t *out_nt, pn_err *err) {
    size_t nh = (size_t)nt * 3;
    pn_half_edge *he = malloc((nh ? nh : 1) * sizeof *he);
    uint32_t *edge_of = malloc((nh ? nh : 1) * sizeof *edge_of);
    double *nsum = calloc((size_t)nv * 3, sizeof *nsum), *bsum = calloc((size_t)nv * 3, sizeof *bsum);
    uint32_t *valence = calloc(nv, sizeof *valence), *bcount = calloc(nv, sizeof *bcount);
    double *np = NULL;
    uint32_t *nix = NULL;
    pn_status st = PN_OK;
    if (!he || !edge_of || !nsum || !bsum || !valence || !bcount) goto oom;
    for (uint32_t t = 0; t < nt; t++)
        for (uint32_t k = 0; k < 3; k++) {
            uint64_t a = ix[3 * t + k], b = ix[3 * t + (k + 1) % 3];
            uint64_t lo = a < b ? a : b, hi = a < b ? b : a;
            he[3 * t + k] = (pn_half_edge){(lo << 32) | hi, 3 * t + k};
        }
    qsort(he, nh, sizeof *he, compare_half_edges);
    /* count unique edges */
    uint32_t ne = 0;
    for (size_t i = 0; i < nh; i++)
        if (i == 0 || he[i].key != he[i - 1].key) ne++;
    if ((uint64_t)nv + ne > 0xFFFFFFFFull || (uint64_t)nt * 4 > 0xFFFFFFFFull / 3) {
        st = pn_err_set(err, PN_ERROR_BAD_INPUT, "loopsubdiv: the subdivided mesh is too large");
        goto done;
    }
    uint32_t nv2 = nv + ne;
    np = malloc((size_t)nv2 * 3 * sizeof *np);
    nix = malloc((size_t)nt * 12 * sizeof *nix);
    if (!np || !nix) goto oom;
    /* odd vertices, and the neighbour sums of the even ones */
    uint32_t e = 0;
    for (size_t i = 0; i < nh;) {
        size_t j = i;
        while (j < nh && he[j].key == he[i].key) j++;
        uint32_t a = (uint32_t)(he[i].key >> 32), b = (uint32_t)(he[i].key & 0xFFFFFFFFu);
        size_t sharing = j - i;
        double *q = &np[3 * (size_t)(nv + e)];
        for (int c = 0; c < 3; c++) {
            nsum[3 * (size_t)a + c] += P[3 * (size_t)b + c];
            nsum[3 * (size_t)b + c] += P[3 * (size_t)a + c];
        }
        valence[a]++;
        valence[b]++;
        if (sharing == 2) {
            uint32_t o0 = ix[3 * (he[i].corner / 3) + (he[i].corner % 3 + 2) % 3];
            uint32_t o1 = ix[3 * (he[i + 1].corner / 3) + (he[i + 1].corner % 3 + 2) % 3];
            for (int c = 0; c < 3; c++)
                q[c] = 0.375 * (P[3 * (size_t)a + c] + P[3 * (size_t)b + c]) +
                       0.125 * (P[3 * (size_t)o0 + c] + P[3 * (size_t)o1 + c]);
        } else {
            for (int c = 0; c < 3; c++) {
                q[c] = 0.5 * (P[3 * (size_t)a + c] + P[3 * (size_t)b + c]);
                bsum[3 * (size_t)a + c] += P[3 * (size_t)b + c];
                bsum[3 * (size_t)b + c] += P[3 * (size_t)a + c];
            }
            bcount[a]++;
            bcount[b]++;
        }
        for (size_t k = i; k < j; k++) edge_of[he[k].corner] = nv + e;
        e++;
        i = j;
    }
    /* even vertices */
    for (uint32_t v = 0; v < nv; v++) {
        double *q = &np[3 * (size_t)v];
        const double *pv = &P[3 * (size_t)v];
        if (bcount[v] == 2) {
            for (int c = 0; c < 3; c++) q[c] = 0.75 * pv[c] + 0.125 * bsum[3 * (size_t)v + c];
        } else if (bcount[v] > 0 || valence[v] < 3) {
            for (int c = 0; c < 3; c++) q[c] = pv[c]; /* corners and non-manifold vertices stay */
        } else {
            double beta = loop_beta(valence[v]);
            double w = 1.0 - (double)valence[v] * beta;
            for (int c = 0; c < 3; c++) q[c] = w * pv[c] + beta * nsum[3 * (size_t)v + c];
        }
    }
    for (uint32_t t = 0; t < nt; t++) {
        uint32_t a = ix[3 * t], b = ix[3 * t + 1], c = ix[3 * t + 2];
        uint32_t ab = edge_of[3 * t], bc = edge_of[3 * t + 1], ca = edge_of[3 * t + 2];
        uint32_t *o = &nix[12 * (size_t)t];
        o[0] = a, o[1] = ab, o[2] = ca;
        o[3] = ab, o[4] = b, o[5] = bc;
        o[6] = ca, o[7] = bc, o[8] = c;
        o[9] = ab, o[10] = bc, o[11] = ca;
    }
    *out_p = np;
    *out_ix = nix;
    *out_nv = nv2;
    *out_nt = nt * 4;
    np = NULL;
    nix = NULL;
    goto done;
oom:
    st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory subdividing a loopsubdiv shape");
done:
    free(he);
    free(edge_of);
    free(nsum);
    free(bsum);
    free(valence);
    free(bcount);
    free(np);
    free(nix);
    return st;
}

pn_status pn_loop_subdivide(pn_mesh_data *d, int levels, pn_err *err) {
    if (levels <= 0 || d->triangle_count == 0) return PN_OK;
    double *P = malloc((size_t)d->vertex_count * 3 * sizeof *P);
    if (!P) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory subdividing a loopsubdiv shape");
    for (size_t i = 0; i < (size_t)d->vertex_count * 3; i++) P[i] = (double)d->positions[i];
    uint32_t *ix = d->indices, nv = d->vertex_count, nt = d->triangle_count;
    bool own_ix = false;
    for (int l = 0; l < levels; l++) {
        double *P2 = NULL;
        uint32_t *ix2 = NULL, nv2 = 0, nt2 = 0;
        pn_status st = loop_level(nv, nt, P, ix, &P2, &ix2, &nv2, &nt2, err);
        free(P);
        if (own_ix) free(ix);
        if (st != PN_OK) return st;
        P = P2;
        ix = ix2;
        nv = nv2;
        nt = nt2;
        own_ix = true;
    }
    float *pf = malloc((size_t)nv * 3 * sizeof *pf);
    if (!pf) {
        free(P);
        free(ix);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory subdividing a loopsubdiv shape");
    }
    for (size_t i = 0; i < (size_t)nv * 3; i++) pf[i] = (float)P[i];
    free(P);
    pn_mesh_data_free(d);
    d->vertex_count = nv;
    d->triangle_count = nt;
    d->positions = pf;
    d->indices = ix;
    return PN_OK;
}
