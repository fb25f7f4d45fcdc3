/* env_regions.c — equal-energy hierarchical partition of an environment map into light-cluster
 * regions, with pre-integrated region radiance, jittered sampling inside a region and bounding
 * cones for horizon culling (Donikian et al. 2006, §4.3 and §5.1). See env_regions.h for the
 * method; Structured Importance Sampling (Agarwal et al. 2003) was the alternative not taken. */
#include "lights/env_regions.h"

#include "core/heap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PN_ENV_VIRTUAL_RES 64
#define PN_ENV_PI_D 3.14159265358979323846

/* ---- the grid: texel coordinates <-> directions ------------------------------------------ */

/* Light-space direction of grid position (u, v) in [0,1]^2 (lat-long: theta = v pi,
 * phi = u 2 pi, as lights.c). */
static vec3 grid_direction(const pn_env_regions *r, double u, double v) {
    if (r->equal_area) return pn_equal_area_square_to_sphere((float)u, (float)v);
    double theta = v * PN_ENV_PI_D, phi = u * 2.0 * PN_ENV_PI_D;
    double st = sin(theta);
    return v3((float)(st * cos(phi)), (float)(st * sin(phi)), (float)cos(theta));
}

/* Radiance of light-space direction wl and the grid texel it falls in (the same texel
 * pn_env_lookup reads for image maps). */
static vec3 grid_lookup(const pn_env_regions *r, const pn_env *env, vec3 wl, int *texel) {
    float u, v;
    vec3 radiance;
    if (r->virtual_grid) {
        pn_equal_area_sphere_to_square(wl, &u, &v);
        radiance = env->constant;
    } else {
        radiance = pn_env_lookup(env, wl, &u, &v);
    }
    int x = (int)(u * (float)r->width), y = (int)(v * (float)r->height);
    if (x < 0) x = 0;
    if (x >= r->width) x = r->width - 1;
    if (y < 0) y = 0;
    if (y >= r->height) y = r->height - 1;
    *texel = y * r->width + x;
    return radiance;
}

static vec3 to_world(const pn_env *env, vec3 wl) {
    return v3_normalize(mat4_apply_vector(&env->world_from_light, wl));
}

/* Angle between two unit vectors, well conditioned for small and large angles. */
static double angle_between(vec3 a, vec3 b) {
    double ax = a.x, ay = a.y, az = a.z, bx = b.x, by = b.y, bz = b.z;
    double cx = ay * bz - az * by, cy = az * bx - ax * bz, cz = ax * by - ay * bx;
    return atan2(sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz);
}

/* ---- the partition --------------------------------------------------------------------- */

typedef struct split_ctx {
    const pn_env_regions *r;
    bool by_area;    /* the map has no energy: split by solid angle instead */
    double *scratch; /* max(width, height) marginal sums */
} split_ctx;

static double split_weight(const split_ctx *c, int x, int y) {
    const pn_env_regions *r = c->r;
    double om = r->row_solid_angle[y];
    return c->by_area ? om : (double)r->texel_lum[(size_t)y * (size_t)r->width + (size_t)x] * om;
}

static bool splittable(const pn_env_region *g, double energy) {
    return energy > 0.0 && (g->x1 - g->x0 > 1 || g->y1 - g->y0 > 1);
}

/* Splits g across its angularly longer side at the texel boundary that best halves its weight;
 * g becomes the first half, *second the other; the weights go to *e_first, *e_second. */
static void split_region(const split_ctx *c, pn_env_region *g, pn_env_region *second, double *e_first,
                         double *e_second) {
    const pn_env_regions *r = c->r;
    int nx = g->x1 - g->x0, ny = g->y1 - g->y0;
    double ext_x, ext_y;
    if (r->equal_area) {
        ext_x = (double)nx / (double)r->width;
        ext_y = (double)ny / (double)r->height;
    } else {
        double t0 = PN_ENV_PI_D * g->y0 / r->height, t1 = PN_ENV_PI_D * g->y1 / r->height;
        double sin_max = (t0 <= 0.5 * PN_ENV_PI_D && t1 >= 0.5 * PN_ENV_PI_D) ? 1.0 : fmax(sin(t0), sin(t1));
        ext_x = nx * (2.0 * PN_ENV_PI_D / r->width) * sin_max;
        ext_y = ny * (PN_ENV_PI_D / r->height);
    }
    bool along_x = ext_x >= ext_y;
    if (along_x && nx < 2) along_x = false;
    if (!along_x && ny < 2) along_x = true;

    int lo = along_x ? g->x0 : g->y0, hi = along_x ? g->x1 : g->y1;
    double *m = c->scratch;
    double total = 0.0;
    for (int i = lo; i < hi; i++) m[i - lo] = 0.0;
    for (int y = g->y0; y < g->y1; y++)
        for (int x = g->x0; x < g->x1; x++) m[(along_x ? x : y) - lo] += split_weight(c, x, y);
    for (int i = 0; i < hi - lo; i++) total += m[i];

    double half = 0.5 * total, prefix = 0.0, best_prefix = 0.0, best_cost = INFINITY;
    int best = lo + (hi - lo) / 2, best_off = hi - lo;
    for (int s = lo + 1; s < hi; s++) {
        prefix += m[s - 1 - lo];
        double cost = fabs(prefix - half);
        int off = abs(2 * s - (lo + hi));
        if (cost < best_cost || (cost == best_cost && off < best_off)) {
            best_cost = cost;
            best_off = off;
            best = s;
            best_prefix = prefix;
        }
    }
    *second = *g;
    if (along_x) {
        g->x1 = best;
        second->x0 = best;
    } else {
        g->y1 = best;
        second->y0 = best;
    }
    *e_first = best_prefix;
    *e_second = fmax(0.0, total - best_prefix);
}

/* ---- per-region pre-integration and bounding cone --------------------------------------- */

/* Cosine of a conservative cone half-angle around world direction d containing region k. The
 * angle to d has no maximum inside a region that does not hold -d, so it is bounded by the
 * boundary: sampled every half texel, plus half the spacing (with slack for curved edges). */
static float region_cos_extent(const pn_env_regions *r, const pn_env *env, int k, vec3 d) {
    const pn_env_region *g = &r->regions[k];
    int anti;
    vec3 anti_l = v3_normalize(mat4_apply_vector(&env->light_from_world, v3_neg(d)));
    (void)grid_lookup(r, env, anti_l, &anti);
    if (r->texel_region[anti] == k) return -1.0f;

    const int cx[5] = {g->x0, g->x1, g->x1, g->x0, g->x0};
    const int cy[5] = {g->y0, g->y0, g->y1, g->y1, g->y0};
    double max_angle = 0.0, max_step = 0.0;
    for (int e = 0; e < 4; e++) {
        int len = abs(cx[e + 1] - cx[e]) + abs(cy[e + 1] - cy[e]);
        int steps = 2 * len;
        vec3 prev = v3(0.0f, 0.0f, 0.0f);
        for (int s = 0; s <= steps; s++) {
            double t = steps ? (double)s / steps : 0.0;
            double px = cx[e] + t * (cx[e + 1] - cx[e]), py = cy[e] + t * (cy[e + 1] - cy[e]);
            vec3 w = to_world(env, grid_direction(r, px / r->width, py / r->height));
            max_angle = fmax(max_angle, angle_between(d, w));
            if (s > 0) max_step = fmax(max_step, angle_between(prev, w));
            prev = w;
        }
    }
    double bound = max_angle + 0.75 * max_step + 1e-5;
    if (bound >= PN_ENV_PI_D) return -1.0f;
    double cb = cos(bound);
    float c = (float)cb;
    if ((double)c > cb) c = nextafterf(c, -2.0f);
    return c;
}

static vec3 texel_rgb(const pn_env_regions *r, const pn_env *env, size_t t) {
    if (r->virtual_grid) return env->constant;
    const float *px = env->rgb + 3 * t;
    return v3_mul(v3(px[0], px[1], px[2]), env->scale);
}

/* Fills the integrals, power, solid angle, direction, sampling tables and cone of every region. */
static void finish_regions(pn_env_regions *r, const pn_env *env) {
    int w = r->width;
    int row_base = 0;
    for (int k = 0; k < r->count; k++) {
        pn_env_region *g = &r->regions[k];
        double rgb[3] = {0.0, 0.0, 0.0}, energy = 0.0, omega = 0.0;
        double dir_e[3] = {0.0, 0.0, 0.0}, dir_a[3] = {0.0, 0.0, 0.0};
        r->row_offset[k] = row_base;
        for (int y = g->y0; y < g->y1; y++) {
            double om = r->row_solid_angle[y], row_total = 0.0;
            double theta = PN_ENV_PI_D * (y + 0.5) / r->height;
            for (int x = g->x0; x < g->x1; x++) {
                size_t t = (size_t)y * (size_t)w + (size_t)x;
                double wt = (double)r->texel_lum[t] * om;
                row_total += wt;
                r->col_cum[t] = row_total;
                vec3 c = texel_rgb(r, env, t);
                rgb[0] += (double)c.x * om;
                rgb[1] += (double)c.y * om;
                rgb[2] += (double)c.z * om;
                vec3 dl;
                if (r->equal_area) {
                    dl = grid_direction(r, (x + 0.5) / w, (y + 0.5) / r->height);
                } else {
                    double phi = 2.0 * PN_ENV_PI_D * (x + 0.5) / w;
                    dl = v3((float)(sin(theta) * cos(phi)), (float)(sin(theta) * sin(phi)), (float)cos(theta));
                }
                dir_e[0] += wt * (double)dl.x;
                dir_e[1] += wt * (double)dl.y;
                dir_e[2] += wt * (double)dl.z;
                dir_a[0] += om * (double)dl.x;
                dir_a[1] += om * (double)dl.y;
                dir_a[2] += om * (double)dl.z;
                omega += om;
            }
            energy += row_total;
            r->row_cum[row_base + (y - g->y0)] = energy;
        }
        row_base += g->y1 - g->y0;

        g->irradiance_rgb_integral = v3((float)rgb[0], (float)rgb[1], (float)rgb[2]);
        g->power = (float)energy;
        g->solid_angle = (float)omega;
        r->total_power += energy;

        double le = sqrt(dir_e[0] * dir_e[0] + dir_e[1] * dir_e[1] + dir_e[2] * dir_e[2]);
        double la = sqrt(dir_a[0] * dir_a[0] + dir_a[1] * dir_a[1] + dir_a[2] * dir_a[2]);
        vec3 dl;
        if (energy > 0.0 && le > 1e-6 * energy)
            dl = v3((float)(dir_e[0] / le), (float)(dir_e[1] / le), (float)(dir_e[2] / le));
        else if (la > 1e-6 * omega)
            dl = v3((float)(dir_a[0] / la), (float)(dir_a[1] / la), (float)(dir_a[2] / la));
        else
            dl = grid_direction(r, 0.5 * (g->x0 + g->x1) / w, 0.5 * (g->y0 + g->y1) / r->height);
        g->direction = to_world(env, dl);
        g->cos_extent = region_cos_extent(r, env, k, g->direction);
    }
}

void pn_env_regions_free(pn_env_regions *r) {
    if (!r) return;
    free(r->regions);
    free(r->texel_region);
    free(r->texel_lum);
    free(r->row_solid_angle);
    free(r->row_cum);
    free(r->row_offset);
    free(r->col_cum);
    memset(r, 0, sizeof *r);
}

pn_status pn_env_regions_build(const pn_env *env, int target_count, pn_env_regions *out, pn_err *err) {
    if (!out) return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "environment regions: no output");
    memset(out, 0, sizeof *out);
    if (!env || target_count < 1)
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "environment regions: need a map and a count >= 1");
    pn_env_regions *r = out;
    r->virtual_grid = env->rgb == NULL;
    r->width = r->virtual_grid ? PN_ENV_VIRTUAL_RES : env->width;
    r->height = r->virtual_grid ? PN_ENV_VIRTUAL_RES : env->height;
    r->equal_area = r->virtual_grid ? true : env->equal_area;
    if (r->width <= 0 || r->height <= 0 || r->width > (1 << 16) || r->height > (1 << 16))
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "environment regions: bad map size %dx%d", r->width, r->height);
    int w = r->width, h = r->height;
    size_t n = (size_t)w * (size_t)h;
    int cap = (size_t)target_count < n ? target_count : (int)n;

    r->regions = calloc((size_t)cap, sizeof *r->regions);
    r->texel_region = malloc(n * sizeof *r->texel_region);
    r->texel_lum = malloc(n * sizeof *r->texel_lum);
    r->row_solid_angle = malloc((size_t)h * sizeof *r->row_solid_angle);
    r->col_cum = malloc(n * sizeof *r->col_cum);
    r->row_offset = malloc((size_t)cap * sizeof *r->row_offset);
    double *energy = malloc((size_t)cap * sizeof *energy);
    pn_heap heap; /* splittable regions by energy; ties in the sift's order (core/heap.h) */
    pn_heap_init(&heap, PN_HEAP_MAX);
    double *scratch = malloc((size_t)(w > h ? w : h) * sizeof *scratch);
    pn_status st = PN_OK;
    if (!r->regions || !r->texel_region || !r->texel_lum || !r->row_solid_angle || !r->col_cum || !r->row_offset ||
        !energy || !pn_heap_reserve(&heap, (size_t)cap) || !scratch) {
        st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for environment regions");
        goto done;
    }

    /* Exact texel solid angles and clamped luminances. */
    for (int y = 0; y < h; y++) {
        if (r->equal_area) {
            r->row_solid_angle[y] = 4.0 * PN_ENV_PI_D / ((double)w * (double)h);
        } else {
            double c0 = cos(PN_ENV_PI_D * y / h), c1 = cos(PN_ENV_PI_D * (y + 1) / h);
            r->row_solid_angle[y] = (2.0 * PN_ENV_PI_D / w) * (c0 - c1);
        }
    }
    bool any_energy = false;
    for (size_t t = 0; t < n; t++) {
        float lum = v3_luminance(texel_rgb(r, env, t));
        if (!(lum > 0.0f) || !isfinite(lum)) lum = 0.0f;
        r->texel_lum[t] = lum;
        any_energy = any_energy || lum > 0.0f;
    }

    /* Largest-energy-first kd splitting. */
    split_ctx ctx = {r, !any_energy, scratch};
    r->regions[0] = (pn_env_region){.x0 = 0, .y0 = 0, .x1 = w, .y1 = h};
    r->count = 1;
    energy[0] = 0.0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) energy[0] += split_weight(&ctx, x, y);
    if (splittable(&r->regions[0], energy[0])) pn_heap_push(&heap, energy[0], 0);
    while (r->count < cap && heap.count > 0) {
        int k = (int)pn_heap_pop(&heap).payload;
        int j = r->count++;
        split_region(&ctx, &r->regions[k], &r->regions[j], &energy[k], &energy[j]);
        if (splittable(&r->regions[k], energy[k])) pn_heap_push(&heap, energy[k], k);
        if (splittable(&r->regions[j], energy[j])) pn_heap_push(&heap, energy[j], j);
    }

    size_t rows = 0;
    for (int k = 0; k < r->count; k++) {
        const pn_env_region *g = &r->regions[k];
        rows += (size_t)(g->y1 - g->y0);
        for (int y = g->y0; y < g->y1; y++)
            for (int x = g->x0; x < g->x1; x++) r->texel_region[(size_t)y * (size_t)w + (size_t)x] = k;
    }
    r->row_cum = malloc(rows * sizeof *r->row_cum);
    if (!r->row_cum) {
        st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for environment regions");
        goto done;
    }
    finish_regions(r, env);

done:
    free(energy);
    pn_heap_free(&heap);
    free(scratch);
    if (st != PN_OK) pn_env_regions_free(r);
    return st;
}

/* ---- queries ---------------------------------------------------------------------------- */

/* First index in cum[0..n) with cum[i] > t (cum non-decreasing), clamped to the last entry of
 * positive width. */
static int search_cum(const double *cum, int n, double t) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (cum[mid] > t)
            hi = mid;
        else
            lo = mid + 1;
    }
    while (lo > 0 && cum[lo] <= (lo ? cum[lo - 1] : 0.0)) lo--;
    return lo;
}

static double region_energy(const pn_env_regions *r, int k) {
    const pn_env_region *g = &r->regions[k];
    return r->row_cum[r->row_offset[k] + (g->y1 - g->y0) - 1];
}

/* Light-space direction at fraction (fx, fy) of texel (x, y), uniform in solid angle inside the
 * texel: the equal-area map preserves area, and for lat-long phi and cos theta are linear. */
static vec3 texel_point(const pn_env_regions *r, int x, int y, double fx, double fy) {
    if (r->equal_area) return grid_direction(r, (x + fx) / r->width, (y + fy) / r->height);
    double phi = 2.0 * PN_ENV_PI_D * (x + fx) / r->width;
    double c0 = cos(PN_ENV_PI_D * y / r->height), c1 = cos(PN_ENV_PI_D * (y + 1) / r->height);
    double ct = c0 + fy * (c1 - c0), st = sqrt(fmax(0.0, 1.0 - ct * ct));
    return v3((float)(st * cos(phi)), (float)(st * sin(phi)), (float)ct);
}

bool pn_env_region_sample(const pn_env_regions *r, const pn_env *env, int k, float u1, float u2, vec3 *wi,
                          vec3 *radiance, float *pdf) {
    if (!r || !env || k < 0 || k >= r->count) return false;
    const pn_env_region *g = &r->regions[k];
    if (!(g->power > 0.0f)) return false;
    int rows = g->y1 - g->y0, cols = g->x1 - g->x0, w = r->width;
    const double *rc = r->row_cum + r->row_offset[k];
    double total = rc[rows - 1];
    if (!(total > 0.0)) return false;

    /* A row by its weight, then a texel of the row by its weight; the leftover of each number
     * places the sample inside the texel. */
    double t = (double)u1 * total;
    int i = search_cum(rc, rows, t);
    double before = i ? rc[i - 1] : 0.0, width = rc[i] - before;
    if (!(width > 0.0)) return false;
    double fy = fmin(fmax((t - before) / width, 0.0), 1.0);
    int y = g->y0 + i;
    const double *cc = r->col_cum + (size_t)y * (size_t)w + (size_t)g->x0;
    double s = (double)u2 * cc[cols - 1];
    int j = search_cum(cc, cols, s);
    before = j ? cc[j - 1] : 0.0;
    width = cc[j] - before;
    if (!(width > 0.0)) return false;
    double fx = fmin(fmax((s - before) / width, 0.0), 1.0);
    int x = g->x0 + j;

    /* Radiance and density from the texel the direction maps back to. Float rounding can put
     * a point on the texel's far edge into the neighbour (outside the region); such a point is
     * moved a little towards the texel centre, where radiance and density are the same. */
    int texel = -1;
    vec3 wl = v3(0.0f, 0.0f, 1.0f), l = v3(0.0f, 0.0f, 0.0f);
    for (int attempt = 0; attempt < 2; attempt++) {
        if (attempt) {
            fx = 0.5 + (fx - 0.5) * 0.999;
            fy = 0.5 + (fy - 0.5) * 0.999;
        }
        wl = texel_point(r, x, y, fx, fy);
        l = grid_lookup(r, env, wl, &texel);
        if (r->texel_region[texel] == k) break;
    }
    if (r->texel_region[texel] != k) return false;
    double lum = (double)r->texel_lum[texel];
    if (!(lum > 0.0)) return false;
    float p = (float)(lum / total);
    if (!(p > 0.0f) || !isfinite(p)) return false;
    *wi = to_world(env, wl);
    *radiance = l;
    *pdf = p;
    return true;
}

float pn_env_region_pdf(const pn_env_regions *r, const pn_env *env, int k, vec3 w) {
    if (!r || !env || k < 0 || k >= r->count || !(r->regions[k].power > 0.0f)) return 0.0f;
    vec3 wl = mat4_apply_vector(&env->light_from_world, w);
    if (!(v3_length2(wl) > 0.0f) || !v3_is_finite(wl)) return 0.0f;
    int texel;
    (void)grid_lookup(r, env, v3_normalize(wl), &texel);
    if (r->texel_region[texel] != k) return 0.0f;
    return (float)((double)r->texel_lum[texel] / region_energy(r, k));
}

int pn_env_region_of(const pn_env_regions *r, const pn_env *env, vec3 w) {
    if (!r || !env || r->count <= 0) return -1;
    vec3 wl = mat4_apply_vector(&env->light_from_world, w);
    if (!(v3_length2(wl) > 0.0f) || !v3_is_finite(wl)) return -1;
    int texel;
    (void)grid_lookup(r, env, v3_normalize(wl), &texel);
    return r->texel_region[texel];
}

bool pn_env_region_below(const pn_env_region *reg, vec3 n) {
    double c = (double)reg->cos_extent;
    if (!(c > 0.0)) return false;
    double nx = n.x, ny = n.y, nz = n.z;
    double len = sqrt(nx * nx + ny * ny + nz * nz);
    if (!(len > 0.0)) return false;
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    double d = (double)reg->direction.x * nx + (double)reg->direction.y * ny + (double)reg->direction.z * nz;
    return d < -(s + 1e-6) * len;
}
