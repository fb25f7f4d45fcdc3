/* projection.c — pbrt-v4's projection light (lights.cpp, ProjectionLight): a point light that
 * shines an image through a perspective frustum; its intensity, direct-light sampling, exact
 * unoccluded irradiance, emission sampling by intensity (for VPL light paths) and power.
 *
 * Geometry, as pbrt-v4 sets it up: the image's shorter side spans [-1, 1] of the screen window
 * and the longer one [-aspect, aspect]; screen = perspective(fov) of light space, so the window
 * seen on the plane z = 1 is [-sx t, sx t] x [-sy t, sy t] with t = tan(fov / 2), of area
 * A = 4 t^2 sx sy. A direction w_l (light space) with w_l.z >= 1e-3 (pbrt's hither) reads the
 * nearest pixel of (w_l.x, w_l.y) / (w_l.z t); pixel row 0 is the top of the image, which lands
 * on +y of the light's frame because pbrt-v4 flips y (scene/lightdefs.c folds the flip into the
 * transform).
 *
 * The solid angle of a patch dA of the plane z = 1 seen from the origin is cos^3(theta) dA, which
 * gives the power, Phi = A * mean over pixels of rgb * cos^3 (pbrt-v4's Phi, midpoint rule per
 * pixel), and the emission density: a pixel chosen with probability proportional to
 * mean(rgb) cos^3 (pbrt-v4 builds the same table) and a uniform point in it on the plane have the
 * solid-angle density pdf_uv / (A cos^3). Under a world transform M that is not a rotation, a
 * unit light-space direction maps to world solid angle with the Jacobian |det M| / |M w_l|^3;
 * here it is kept, so that the density is exact in world space (pbrt-v4 reports the light-space
 * one). */
#include "lights/lights.h"

#include "core/sampling.h"
#include "scene/scene.h"

#include <stdlib.h>

#define PN_PROJECTION_HITHER 1e-3f

/* The pixel that light-space direction wl reads, or false outside the frustum. */
static bool projection_pixel(const pn_projection *pr, vec3 wl, int *x, int *y, float *u, float *v) {
    if (!(wl.z >= PN_PROJECTION_HITHER)) return false;
    float inv = 1.0f / (wl.z * pr->tan_half_fov);
    float px = wl.x * inv, py = wl.y * inv;
    if (!(px >= -pr->sx && px <= pr->sx && py >= -pr->sy && py <= pr->sy)) return false;
    *u = (px + pr->sx) / (2.0f * pr->sx);
    *v = (py + pr->sy) / (2.0f * pr->sy);
    int ix = (int)(*u * (float)pr->width), iy = (int)(*v * (float)pr->height);
    *x = ix < 0 ? 0 : (ix >= pr->width ? pr->width - 1 : ix);
    *y = iy < 0 ? 0 : (iy >= pr->height ? pr->height - 1 : iy);
    return true;
}

static vec3 pixel_rgb(const pn_projection *pr, int x, int y) {
    const float *c = pr->rgb + 3 * ((size_t)y * (size_t)pr->width + (size_t)x);
    return v3(fmaxf(0.0f, c[0]), fmaxf(0.0f, c[1]), fmaxf(0.0f, c[2]));
}

vec3 pn_projection_factor(const pn_lights *lights, const pn_light *l, vec3 w) {
    const pn_projection *pr = &lights->projections[l->env];
    vec3 wl = mat4_apply_vector(&pr->light_from_world, w);
    int x, y;
    float u, v;
    if (!projection_pixel(pr, wl, &x, &y, &u, &v)) return v3(0, 0, 0);
    return pixel_rgb(pr, x, y);
}

float pn_projection_pdf(const pn_lights *lights, const pn_light *l, vec3 w) {
    const pn_projection *pr = &lights->projections[l->env];
    if (!pr->dist) return 0.0f;
    vec3 wl = mat4_apply_vector(&pr->light_from_world, w);
    int x, y;
    float u, v;
    if (!projection_pixel(pr, wl, &x, &y, &u, &v)) return 0.0f;
    /* The pixel's own density (u, v of its centre), so that a direction on a pixel edge gets the
     * density of the pixel whose colour it reads. */
    float pdf_uv =
        pn_distribution2d_pdf(pr->dist, ((float)x + 0.5f) / (float)pr->width, ((float)y + 0.5f) / (float)pr->height);
    /* wl = M^-1 w for unit w: the world density is pdf_uv / (A |det M| wl.z^3) (file comment). */
    float z3 = wl.z * wl.z * wl.z;
    float pdf = pdf_uv / (pr->plane_area * pr->abs_det * z3);
    return isfinite(pdf) ? pdf : 0.0f;
}

bool pn_projection_sample_direction(const pn_lights *lights, const pn_light *l, float u1, float u2, vec3 *w,
                                    float *pdf) {
    const pn_projection *pr = &lights->projections[l->env];
    float u, v, pdf_uv;
    if (!pr->dist || !pn_distribution2d_sample(pr->dist, u1, u2, &u, &v, &pdf_uv)) return false;
    float t = pr->tan_half_fov;
    vec3 wl = v3((2.0f * u - 1.0f) * pr->sx * t, (2.0f * v - 1.0f) * pr->sy * t, 1.0f);
    vec3 d = mat4_apply_vector(&pr->world_from_light, wl);
    float len = v3_length(d);
    if (!(len > 0.0f) || !isfinite(len)) return false;
    *w = v3_scale(d, 1.0f / len);
    /* Read back from the direction, as the intensity will be (a sample within rounding of a
     * pixel edge may map into the neighbour). */
    *pdf = pn_projection_pdf(lights, l, *w);
    return *pdf > 0.0f;
}

bool pn_projection_sample_li(const pn_lights *lights, const pn_light *l, vec3 p, pn_light_sample *s) {
    vec3 d = v3_sub(l->p, p);
    float d2 = v3_length2(d);
    if (!(d2 > 0.0f)) return false;
    float dist = sqrtf(d2);
    s->wi = v3_scale(d, 1.0f / dist);
    s->dist = dist;
    vec3 f = pn_projection_factor(lights, l, v3_neg(s->wi));
    if (v3_is_zero(f)) return false;
    s->radiance = v3_scale(v3_mul(l->emit, f), 1.0f / d2);
    s->pdf = 1.0f;
    s->delta = true;
    return true;
}

float pn_projection_irradiance(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n) {
    vec3 d = v3_sub(l->p, p);
    float d2 = v3_length2(d);
    if (!(d2 > 0.0f)) return 0.0f;
    vec3 wi = v3_scale(d, 1.0f / sqrtf(d2));
    float c = v3_dot(n, wi);
    if (c <= 0.0f) return 0.0f;
    vec3 f = pn_projection_factor(lights, l, v3_neg(wi));
    return fmaxf(0.0f, v3_luminance(v3_mul(l->emit, f))) * c / d2;
}

double pn_projection_unit_power(const float *rgb, int width, int height, double fov_deg) {
    double aspect = (double)width / (double)height;
    double sx = aspect > 1.0 ? aspect : 1.0, sy = aspect > 1.0 ? 1.0 : 1.0 / aspect;
    double t = tan(fov_deg * 3.14159265358979323846 / 360.0);
    double sum = 0.0;
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            double px = (2.0 * ((double)x + 0.5) / width - 1.0) * sx * t;
            double py = (2.0 * ((double)y + 0.5) / height - 1.0) * sy * t;
            double r2 = 1.0 + px * px + py * py;
            const float *c = rgb + 3 * ((size_t)y * (size_t)width + (size_t)x);
            vec3 v = v3(fmaxf(0.0f, c[0]), fmaxf(0.0f, c[1]), fmaxf(0.0f, c[2]));
            sum += (double)v3_luminance(v) / (r2 * sqrt(r2));
        }
    return 4.0 * t * t * sx * sy * sum / ((double)width * (double)height);
}

pn_status pn_projection_prepare(const struct pn_scene_s *scene, const struct pn_light_def *d, pn_projection *pr,
                                pn_light *l, pn_err *err) {
    const pn_texture_image *img = &scene->images[d->image];
    pr->width = img->width;
    pr->height = img->height;
    pr->rgb = img->rgb;
    pr->world_from_light = d->world_from_light;
    pr->light_from_world = d->light_from_world;
    pr->abs_det = (float)fabs(mat4_det3(&d->world_from_light));
    double aspect = (double)img->width / (double)img->height;
    pr->sx = aspect > 1.0 ? (float)aspect : 1.0f;
    pr->sy = aspect > 1.0 ? 1.0f : (float)(1.0 / aspect);
    double t = tan((double)d->fov_deg * 3.14159265358979323846 / 360.0);
    pr->tan_half_fov = (float)t;
    pr->plane_area = (float)(4.0 * t * t * (double)pr->sx * (double)pr->sy);

    size_t n = (size_t)img->width * (size_t)img->height;
    float *weight = malloc(n * sizeof *weight);
    if (!weight) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a projection light");
    double phi[3] = {0.0, 0.0, 0.0}, max_sum = 0.0;
    float peak = 0.0f;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            /* The pixel centre on the plane z = 1, and the cos^3 of its direction. */
            double px = (2.0 * ((double)x + 0.5) / img->width - 1.0) * (double)pr->sx * t;
            double py = (2.0 * ((double)y + 0.5) / img->height - 1.0) * (double)pr->sy * t;
            double r2 = 1.0 + px * px + py * py;
            double cos3 = 1.0 / (r2 * sqrt(r2));
            vec3 c = pixel_rgb(pr, x, y);
            phi[0] += (double)c.x * cos3;
            phi[1] += (double)c.y * cos3;
            phi[2] += (double)c.z * cos3;
            float m = v3_max_component(c);
            max_sum += (double)m;
            peak = fmaxf(peak, m);
            weight[(size_t)y * (size_t)img->width + (size_t)x] = (float)((double)(c.x + c.y + c.z) / 3.0 * cos3);
        }
    double k = (double)pr->plane_area / (double)n;
    pr->phi = v3((float)(phi[0] * k), (float)(phi[1] * k), (float)(phi[2] * k));
    pr->peak = peak;
    pr->mean_max = (float)(max_sum / (double)n);
    pr->dist = pn_distribution2d_create(weight, img->width, img->height); /* NULL for a black image */
    free(weight);

    l->kind = PN_LIGHT_PROJECTION;
    l->p = d->position;
    l->emit = d->intensity;
    l->power = fmaxf(0.0f, v3_luminance(v3_mul(l->emit, pr->phi)));
    l->n = v3_normalize(mat4_apply_vector(&d->world_from_light, v3(0, 0, 1)));
    /* The narrowest cone around the axis holding the frustum's four edges holds all of it (the
     * frustum is their conic hull and the cone is convex); rounded down to stay conservative. */
    float cos_min = 1.0f;
    for (int k2 = 0; k2 < 4; k2++) {
        vec3 corner =
            v3((k2 & 1 ? 1.0f : -1.0f) * pr->sx * (float)t, (k2 & 2 ? 1.0f : -1.0f) * pr->sy * (float)t, 1.0f);
        vec3 wc = v3_normalize(mat4_apply_vector(&d->world_from_light, corner));
        cos_min = fminf(cos_min, v3_dot(wc, l->n));
    }
    l->cos_total_width = fmaxf(-1.0f, cos_min - 1e-5f);
    return PN_OK;
}
