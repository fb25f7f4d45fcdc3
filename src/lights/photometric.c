/* photometric.c — measured luminaires (IES LM-63, EULUMDAT) as goniometric lights: the frame,
 * the importance sampling of emitted directions that starts VPL light paths, and the numbers
 * the bounds use (peak, lumens, the emission cone).
 *
 * The intensity is emit * factor(w) with emit = colour * peak candela * scale and factor =
 * candela(w) / peak <= 1 (pn_gonio_factor), so every bound that holds for a point light of
 * intensity emit (the light BVH's phi, the cuts' M G I bound of an omni VPL, ias's cluster
 * intensity) holds for the luminaire; exact evaluation goes through the file's bilinear table
 * (scene/photometry.c).
 *
 * Emission sampling: a piecewise-constant density over a grid of (phi, gamma) cells, phi =
 * 2 pi u from C = 0, gamma = pi v from nadir, each cell weighted by the largest intensity at its
 * four corners and centre times its solid angle (cos gamma0 - cos gamma1), plus a floor of 1e-4
 * of the peak (so no cell where the table is lit between the probes has density 0: the light
 * paths stay unbiased). Inside a cell (u, v) is uniform, so the solid-angle density is
 * pdf_uv / (2 pi^2 sin gamma); a path carries I(w) / pdf(w). The table is built once per file
 * and shared by the lights that use it. */
#include "lights/lights.h"

#include "core/context.h"
#include "core/sampling.h"
#include "io/image.h"
#include "scene/photometry.h"
#include "scene/scene.h"

#include <math.h>
#include <stdlib.h>

enum { PHOTOMETRIC_PHI_CELLS = 256, PHOTOMETRIC_GAMMA_CELLS = 512 };

#define PHOTO_PI 3.14159265358979323846

static vec3 light_dir(double u, double v) {
    double phi = 2.0 * PHOTO_PI * u, gamma = PHOTO_PI * v;
    return v3((float)(sin(gamma) * cos(phi)), (float)(sin(gamma) * sin(phi)), (float)(-cos(gamma)));
}

static pn_distribution2d *build_distribution(const pn_photometry *p, pn_err *err, pn_status *st) {
    const int nu = PHOTOMETRIC_PHI_CELLS, nv = PHOTOMETRIC_GAMMA_CELLS;
    float *corner = malloc((size_t)(nu + 1) * (size_t)(nv + 1) * sizeof *corner);
    float *w = malloc((size_t)nu * (size_t)nv * sizeof *w);
    pn_distribution2d *d = NULL;
    *st = PN_OK;
    if (!corner || !w) {
        *st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a luminaire's sampling table");
        goto done;
    }
    for (int j = 0; j <= nv; j++)
        for (int i = 0; i <= nu; i++)
            corner[(size_t)j * (nu + 1) + i] = (float)pn_photometry_eval(p, light_dir((double)i / nu, (double)j / nv));
    double floor_cd = 1e-4 * p->peak_cd;
    for (int j = 0; j < nv; j++) {
        double g0 = PHOTO_PI * j / nv, g1 = PHOTO_PI * (j + 1) / nv;
        double solid = cos(g0) - cos(g1);
        for (int i = 0; i < nu; i++) {
            double m = pn_photometry_eval(p, light_dir((i + 0.5) / nu, (j + 0.5) / nv));
            for (int dj = 0; dj <= 1; dj++)
                for (int di = 0; di <= 1; di++) m = fmax(m, corner[(size_t)(j + dj) * (nu + 1) + i + di]);
            w[(size_t)j * nu + i] = (float)((m + floor_cd) * solid);
        }
    }
    d = pn_distribution2d_create(w, nu, nv);
    if (!d) *st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a luminaire's sampling table");
done:
    free(corner);
    free(w);
    return d;
}

/* True when the 3x3 part of m maps angles to equal angles (a rotation, mirror, uniform scale). */
static bool preserves_angles(const mat4 *m) {
    vec3 c[3];
    for (int k = 0; k < 3; k++) c[k] = mat4_apply_vector(m, v3(k == 0, k == 1, k == 2));
    float l0 = v3_length2(c[0]);
    for (int a = 0; a < 3; a++) {
        if (fabsf(v3_length2(c[a]) - l0) > 1e-4f * l0) return false;
        for (int b = a + 1; b < 3; b++)
            if (fabsf(v3_dot(c[a], c[b])) > 1e-4f * l0) return false;
    }
    return l0 > 0.0f;
}

pn_status pn_gonio_prepare_photometric(const struct pn_scene_s *scene, const struct pn_light_def *d, pn_gonio *g,
                                       const pn_gonio *earlier, int earlier_count, pn_err *err) {
    const pn_photometry *p = scene->photometries[d->photometry];
    g->photo = p;
    g->inv_peak_cd = 1.0 / p->peak_cd;
    g->peak = 1.0f;
    g->world_from_light = d->world_from_light;
    g->light_from_world = d->light_from_world;
    g->abs_det = (float)fabs(mat4_det3(&d->world_from_light));
    g->nadir = v3_normalize(mat4_apply_vector(&d->world_from_light, v3(0, 0, -1)));
    g->rigid = preserves_angles(&d->world_from_light);
    g->cos_max_gamma = p->type == PN_PHOTOMETRY_TYPE_C && p->max_gamma_deg < 180.0
                           ? (float)cos(p->max_gamma_deg * PHOTO_PI / 180.0)
                           : -1.0f;
    for (int i = 0; i < earlier_count; i++)
        if (earlier[i].photo == p && earlier[i].dist) {
            g->dist = earlier[i].dist;
            g->owns_dist = false;
            return PN_OK;
        }
    pn_status st;
    g->dist = build_distribution(p, err, &st);
    g->owns_dist = g->dist != NULL;
    return st;
}

bool pn_gonio_sample_direction(const pn_lights *lights, const pn_light *l, float u1, float u2, vec3 *w, float *pdf) {
    const pn_gonio *g = &lights->gonios[l->env];
    float u, v, pdf_uv;
    if (!g->dist || !pn_distribution2d_sample(g->dist, u1, u2, &u, &v, &pdf_uv)) return false;
    double s = sin(PHOTO_PI * (double)v);
    if (!(s > 1e-7)) return false;
    vec3 ww = mat4_apply_vector(&g->world_from_light, light_dir(u, v));
    float len = v3_length(ww);
    if (!(len > 0.0f)) return false;
    *w = v3_scale(ww, 1.0f / len);
    *pdf = (float)((double)pdf_uv / (2.0 * PHOTO_PI * PHOTO_PI * s)) * len * len * len / g->abs_det;
    return *pdf > 0.0f && isfinite(*pdf);
}

float pn_gonio_pdf(const pn_lights *lights, const pn_light *l, vec3 w) {
    const pn_gonio *g = &lights->gonios[l->env];
    if (!g->dist) return 0.0f;
    vec3 wl = mat4_apply_vector(&g->light_from_world, w);
    float len = v3_length(wl);
    if (!(len > 0.0f)) return 0.0f;
    wl = v3_scale(wl, 1.0f / len);
    double gamma = acos(fmax(-1.0, fmin(1.0, -(double)wl.z)));
    double phi = atan2((double)wl.y, (double)wl.x);
    if (phi < 0.0) phi += 2.0 * PHOTO_PI;
    double s = sin(gamma);
    if (!(s > 1e-7)) return 0.0f;
    float pdf_uv = pn_distribution2d_pdf(g->dist, (float)(phi / (2.0 * PHOTO_PI)), (float)(gamma / PHOTO_PI));
    return (float)((double)pdf_uv / (2.0 * PHOTO_PI * PHOTO_PI * s)) / (g->abs_det * len * len * len);
}

float pn_gonio_photometric_power(const pn_lights *lights, const pn_light *l) {
    const pn_gonio *g = &lights->gonios[l->env];
    return fmaxf(0.0f, v3_luminance(l->emit)) * (float)(g->photo->lumens * g->inv_peak_cd);
}

/* ---------------------------------------------------------------- pbrt-v4's goniometric image */

pn_status pn_photometry_goniometric_image(pn_context ctx, const char *path, int resolution, pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !path || !out_image || resolution < 1 || resolution > 16384) {
        if (ctx) pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_photometry_goniometric_image: bad arguments");
        return PN_ERROR_INVALID_ARGUMENT;
    }
    pn_err err;
    pn_err_init(&err);
    if (!pn_photometry_is_file(path)) {
        pn_err_set(&err, PN_ERROR_BAD_INPUT, "%s: not a photometric file (.ies or .ldt)", path);
        return pn_context_fail_from(ctx, &err);
    }
    pn_photometry *p = NULL;
    pn_status st = pn_photometry_read(path, path, &p, &err);
    if (st != PN_OK) return pn_context_fail_from(ctx, &err);
    pn_image img = pn_image_create(resolution, resolution);
    if (!img) {
        pn_photometry_free(p);
        return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %d x %d image", resolution,
                               resolution);
    }
    float *rgb = img->layers[0].data;
    enum { SUB = 4 };
    for (int y = 0; y < resolution; y++)
        for (int x = 0; x < resolution; x++) {
            /* the equal-area map: equal solid angle per sub-sample, so their mean is the pixel's
             * mean candela (and pbrt-v4's 4 pi mean(image) its lumens) */
            double sum = 0.0;
            for (int sy = 0; sy < SUB; sy++)
                for (int sx = 0; sx < SUB; sx++) {
                    float u = ((float)x + ((float)sx + 0.5f) / SUB) / (float)resolution;
                    float v = ((float)y + ((float)sy + 0.5f) / SUB) / (float)resolution;
                    vec3 w = pn_equal_area_square_to_sphere(u, v); /* pbrt's light frame (y, z swapped) */
                    sum += pn_photometry_eval(p, v3(w.x, w.z, w.y));
                }
            float c = (float)(sum / (SUB * SUB));
            float *px = rgb + 3 * ((size_t)y * (size_t)resolution + (size_t)x);
            px[0] = px[1] = px[2] = c;
        }
    pn_photometry_free(p);
    *out_image = img;
    return PN_OK;
}
