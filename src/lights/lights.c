/* lights.c — light records built from the scene, evaluation of emitters and environment maps,
 * and the unoccluded-irradiance estimate used for the reference light PDF (IAS paper §5.1). */
#include "lights/lights.h"

#include "accel/accel.h"
#include "core/sampling.h"
#include "core/warn.h"
#include "scene/photometry.h"
#include "scene/scene.h"
#include "spectral/transport.h"

#include <stdlib.h>
#include <string.h>

/* ---- equal-area octahedral mapping (Clarberg 2008, as used by pbrt-v4 for env maps) ------ */

vec3 pn_equal_area_square_to_sphere(float u, float v) {
    float x = 2.0f * u - 1.0f, y = 2.0f * v - 1.0f;
    float ax = fabsf(x), ay = fabsf(y);
    float signed_distance = 1.0f - (ax + ay);
    float d = fabsf(signed_distance);
    float r = 1.0f - d;
    float phi = (r == 0.0f ? 1.0f : (ay - ax) / r + 1.0f) * (PN_PI / 4.0f);
    float z = copysignf(1.0f - r * r, signed_distance);
    float cos_phi = copysignf(cosf(phi), x);
    float sin_phi = copysignf(sinf(phi), y);
    float s = r * sqrtf(fmaxf(0.0f, 2.0f - r * r));
    return v3(cos_phi * s, sin_phi * s, z);
}

void pn_equal_area_sphere_to_square(vec3 d, float *u, float *v) {
    float x = fabsf(d.x), y = fabsf(d.y), z = fabsf(d.z);
    float r = sqrtf(fmaxf(0.0f, 1.0f - z));
    float a = fmaxf(x, y), b = fminf(x, y);
    b = a == 0.0f ? 0.0f : b / a;
    float phi = atanf(b) * (2.0f / PN_PI);
    if (x < y) phi = 1.0f - phi;
    float vv = phi * r;
    float uu = r - vv;
    if (d.z < 0.0f) {
        float t = uu;
        uu = vv;
        vv = t;
        uu = 1.0f - uu;
        vv = 1.0f - vv;
    }
    uu = copysignf(uu, d.x);
    vv = copysignf(vv, d.y);
    *u = 0.5f * (uu + 1.0f);
    *v = 0.5f * (vv + 1.0f);
}

/* ---- environment maps --------------------------------------------------------------------- */

static void env_direction_to_uv(const pn_env *env, vec3 wl, float *u, float *v) {
    if (env->equal_area) {
        pn_equal_area_sphere_to_square(wl, u, v);
    } else {
        /* atan2 rather than acos: well conditioned near the poles, so that the direction of a
         * sampled texel maps back to that texel. */
        float theta = atan2f(sqrtf(wl.x * wl.x + wl.y * wl.y), wl.z);
        float phi = atan2f(wl.y, wl.x);
        if (phi < 0.0f) phi += 2.0f * PN_PI;
        *u = phi * (0.5f * PN_INV_PI);
        *v = theta * PN_INV_PI;
    }
}

static vec3 env_texel(const pn_env *env, float u, float v) {
    if (!env->rgb) return env->constant;
    int x = (int)(u * (float)env->width), y = (int)(v * (float)env->height);
    if (x < 0) x = 0;
    if (x >= env->width) x = env->width - 1;
    if (y < 0) y = 0;
    if (y >= env->height) y = env->height - 1;
    const float *px = env->rgb + 3 * ((size_t)y * (size_t)env->width + (size_t)x);
    return v3_mul(v3(px[0], px[1], px[2]), env->scale);
}

vec3 pn_env_lookup(const pn_env *env, vec3 wl, float *u, float *v) {
    env_direction_to_uv(env, wl, u, v);
    return env_texel(env, *u, *v);
}

vec3 pn_env_radiance(const pn_env *env, vec3 d) {
    if (!env->rgb) return env->constant;
    vec3 wl = v3_normalize(mat4_apply_vector(&env->light_from_world, d));
    float u, v;
    env_direction_to_uv(env, wl, &u, &v);
    return env_texel(env, u, v);
}

vec3 pn_lights_environment_radiance(const pn_lights *lights, vec3 d) {
    vec3 sum = v3(0, 0, 0);
    for (int i = 0; i < lights->env_count; i++) sum = v3_add(sum, pn_env_radiance(&lights->envs[i], d));
    return sum;
}

/* Real spherical harmonics up to order 2 at the unit direction d. */
static void sh9(vec3 d, double y[9]) {
    double x = (double)d.x, yy = (double)d.y, z = (double)d.z;
    y[0] = 0.282095;
    y[1] = 0.488603 * yy;
    y[2] = 0.488603 * z;
    y[3] = 0.488603 * x;
    y[4] = 1.092548 * x * yy;
    y[5] = 1.092548 * yy * z;
    y[6] = 0.315392 * (3.0 * z * z - 1.0);
    y[7] = 1.092548 * x * z;
    y[8] = 0.546274 * (x * x - yy * yy);
}

/* Projects the luminance of the map onto 9 spherical harmonics (light space), so that the
 * unoccluded irradiance for any normal follows from them (Ramamoorthi and Hanrahan 2001,
 * "An Efficient Representation for Irradiance Environment Maps": E(n) = sum of A_l L_lm
 * Y_lm(n) with A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4; error a few percent). */
static void env_project_sh(pn_env *env) {
    double acc[9] = {0};
    for (int y = 0; y < env->height; y++)
        for (int x = 0; x < env->width; x++) {
            float u = ((float)x + 0.5f) / (float)env->width, v = ((float)y + 0.5f) / (float)env->height;
            vec3 d;
            double solid_angle;
            if (env->equal_area) {
                d = pn_equal_area_square_to_sphere(u, v);
                solid_angle = 4.0 * (double)PN_PI / ((double)env->width * (double)env->height);
            } else {
                float theta = v * PN_PI, phi = u * 2.0f * PN_PI;
                d = v3(sinf(theta) * cosf(phi), sinf(theta) * sinf(phi), cosf(theta));
                solid_angle = (2.0 * (double)PN_PI / env->width) * ((double)PN_PI / env->height) * sin((double)theta);
            }
            const float *px = env->rgb + 3 * ((size_t)y * (size_t)env->width + (size_t)x);
            double lum = (double)fmaxf(0.0f, v3_luminance(v3_mul(v3(px[0], px[1], px[2]), env->scale)));
            double b[9];
            sh9(d, b);
            for (int k = 0; k < 9; k++) acc[k] += lum * b[k] * solid_angle;
        }
    static const double band[9] = {1.0, 2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0, 0.25, 0.25, 0.25, 0.25, 0.25};
    for (int k = 0; k < 9; k++) env->irradiance_sh[k] = (float)(acc[k] * band[k] * (double)PN_PI);
    env->has_sh = true;
}

/* Unoccluded irradiance (luminance) from the environment on a surface with world normal n. */
static float env_irradiance(const pn_env *env, vec3 n) {
    float floor_value = 0.02f * PN_PI * env->average_luminance;
    if (!env->has_sh) return PN_PI * env->average_luminance;
    vec3 nl = v3_normalize(mat4_apply_vector(&env->light_from_world, n));
    double b[9];
    sh9(nl, b);
    double e = 0.0;
    for (int k = 0; k < 9; k++) e += (double)env->irradiance_sh[k] * b[k];
    /* The harmonics ring and may dip to zero or below where the true value is small but not
     * zero: a floor keeps every such direction sampleable. */
    return fmaxf((float)e, floor_value);
}

static pn_status env_prepare(pn_env *env, pn_err *err) {
    if (!env->rgb) {
        env->average_luminance = v3_luminance(env->constant);
        return PN_OK;
    }
    size_t n = (size_t)env->width * (size_t)env->height;
    float *w = malloc(n * sizeof *w);
    if (!w) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the environment map");
    double lum_sum = 0.0, solid_sum = 0.0;
    for (int y = 0; y < env->height; y++) {
        float sin_theta = 1.0f;
        if (!env->equal_area) sin_theta = sinf(PN_PI * ((float)y + 0.5f) / (float)env->height);
        for (int x = 0; x < env->width; x++) {
            const float *px = env->rgb + 3 * ((size_t)y * (size_t)env->width + (size_t)x);
            vec3 c = v3_mul(v3(px[0], px[1], px[2]), env->scale);
            /* The mean of the channels is positive wherever any channel is, so no radiance
             * is left without sampling probability. */
            float weight = fmaxf(0.0f, (c.x + c.y + c.z) / 3.0f);
            w[(size_t)y * (size_t)env->width + (size_t)x] = weight * sin_theta;
            lum_sum += (double)(fmaxf(0.0f, v3_luminance(c)) * sin_theta);
            solid_sum += (double)sin_theta;
        }
    }
    env->average_luminance = solid_sum > 0.0 ? (float)(lum_sum / solid_sum) : 0.0f;
    env_project_sh(env);
    env->dist = pn_distribution2d_create(w, env->width, env->height);
    free(w);
    if (!env->dist && env->average_luminance > 0.0f)
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the environment map");
    return PN_OK;
}

/* ---- building ----------------------------------------------------------------------------- */

typedef struct light_list {
    pn_light *items;
    int count, cap;
} light_list;

static pn_light *push_light(light_list *ll, pn_err *err) {
    if (ll->count == ll->cap) {
        int cap = ll->cap ? ll->cap * 2 : 64;
        pn_light *n = realloc(ll->items, (size_t)cap * sizeof *n);
        if (!n) {
            pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for lights");
            return NULL;
        }
        ll->items = n;
        ll->cap = cap;
    }
    pn_light *l = &ll->items[ll->count++];
    memset(l, 0, sizeof *l);
    l->env = -1;
    l->mesh = -1;
    l->prim = -1;
    return l;
}

static vec3 mesh_vertex(const pn_mesh *m, uint32_t i) {
    return v3(m->positions[3 * (size_t)i], m->positions[3 * (size_t)i + 1], m->positions[3 * (size_t)i + 2]);
}

/* The emitting normal of triangle t, by pbrt's rules (see pn_mesh.flip_normals). */
static vec3 triangle_emit_normal(const pn_mesh *m, uint32_t t) {
    const uint32_t *idx = m->indices + 3 * (size_t)t;
    vec3 p0 = mesh_vertex(m, idx[0]), p1 = mesh_vertex(m, idx[1]), p2 = mesh_vertex(m, idx[2]);
    vec3 n = v3_normalize(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0)));
    if (m->flip_normals) n = v3_neg(n);
    if (m->normals) {
        vec3 ns = v3(0, 0, 0);
        for (int k = 0; k < 3; k++)
            ns = v3_add(ns, v3(m->normals[3 * (size_t)idx[k]], m->normals[3 * (size_t)idx[k] + 1],
                               m->normals[3 * (size_t)idx[k] + 2]));
        if (v3_dot(ns, n) < 0.0f) n = v3_neg(n);
    }
    return n;
}

/* If triangles a and b form a rectangle, returns true with its corner and edges. */
static bool pair_is_rectangle(const pn_mesh *m, uint32_t a, uint32_t b, vec3 na, vec3 nb, vec3 *p0, vec3 *e1,
                              vec3 *e2) {
    if (v3_dot(na, nb) < 0.9999f) return false;
    const uint32_t *ia = m->indices + 3 * (size_t)a, *ib = m->indices + 3 * (size_t)b;
    vec3 va[3], vb[3];
    for (int k = 0; k < 3; k++) {
        va[k] = mesh_vertex(m, ia[k]);
        vb[k] = mesh_vertex(m, ib[k]);
    }
    float scale = fmaxf(v3_length(v3_sub(va[1], va[0])), v3_length(v3_sub(va[2], va[0])));
    float tol = 1e-4f * scale;
    /* Find the vertex of a not shared with b, and the vertex of b not shared with a. */
    int shared_a[3] = {0, 0, 0}, shared_b[3] = {0, 0, 0}, shared = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (v3_length(v3_sub(va[i], vb[j])) <= tol && !shared_b[j]) {
                shared_a[i] = shared_b[j] = 1;
                shared++;
                break;
            }
    if (shared != 2) return false;
    int xa = -1, xb = -1, s1 = -1, s2 = -1;
    for (int i = 0; i < 3; i++) {
        if (!shared_a[i])
            xa = i;
        else if (s1 < 0)
            s1 = i;
        else
            s2 = i;
    }
    for (int j = 0; j < 3; j++)
        if (!shared_b[j]) xb = j;
    vec3 x = va[xa], y = vb[xb], c1 = va[s1], c2 = va[s2];
    /* Parallelogram: the diagonals bisect each other; rectangle: right angle at x. */
    if (v3_length(v3_sub(v3_add(x, y), v3_add(c1, c2))) > 2.0f * tol) return false;
    vec3 d1 = v3_sub(c1, x), d2 = v3_sub(c2, x);
    if (fabsf(v3_dot(d1, d2)) > 1e-4f * v3_length(d1) * v3_length(d2)) return false;
    /* Order the edges so that cross(e1, e2) points along the emitting normal. */
    if (v3_dot(v3_cross(d1, d2), na) < 0.0f) {
        vec3 t = d1;
        d1 = d2;
        d2 = t;
    }
    *p0 = x;
    *e1 = d1;
    *e2 = d2;
    return true;
}

static float triangle_area(const pn_mesh *m, uint32_t t) {
    const uint32_t *idx = m->indices + 3 * (size_t)t;
    vec3 p0 = mesh_vertex(m, idx[0]);
    return 0.5f * v3_length(v3_cross(v3_sub(mesh_vertex(m, idx[1]), p0), v3_sub(mesh_vertex(m, idx[2]), p0)));
}

float pn_emission_area_scale(const pn_mesh *m, const pn_emission *e, uint32_t t) {
    if (!e || e->per_shape == 0 || !m || t >= m->triangle_count) return 1.0f;
    float a = triangle_area(m, t);
    if (e->per_shape == 2) {
        uint32_t other = t ^ 1u; /* the patch's other triangle */
        if (other < m->triangle_count) a += triangle_area(m, other);
    }
    return a > 0.0f ? 1.0f / a : 0.0f;
}

/* pbrt-v4 creates no area light for a shape whose material is "interface" (scene.cpp). */
static bool is_interface(const struct pn_scene_s *scene, int material) {
    return material >= 0 && material < scene->material_count &&
           scene->materials[material].kind == PN_MATERIAL_INTERFACE;
}

static pn_status add_mesh_lights(struct pn_scene_s *scene, int mi, light_list *ll, pn_err *err) {
    const pn_mesh *m = &scene->meshes[mi];
    const pn_emission *em = &scene->emissions[m->emission];
    if (m->disk >= 0 && m->disk < scene->disk_count) {
        const pn_disk *d = &scene->disks[m->disk];
        pn_light *l = push_light(ll, err);
        if (!l) return err->status;
        l->kind = PN_LIGHT_DISK;
        l->p = d->center;
        l->n = d->normal;
        l->radius = d->radius;
        l->area = PN_PI * d->radius * d->radius;
        l->emit = em->radiance;
        l->two_sided = em->two_sided;
        l->kelvin = em->kelvin;
        l->kelvin_scale = em->kelvin_scale;
        l->spd = em->spd;
        l->mesh = mi;
        if (d->inner_radius > 0.0f)
            pn_warn(scene->ctx, &scene->warnings, "%s: the disk light's inner radius is ignored for light sampling",
                    m->source ? m->source : "disk");
        return PN_OK;
    }
    int dropped = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *idx = m->indices + 3 * (size_t)t;
        vec3 p0 = mesh_vertex(m, idx[0]), p1 = mesh_vertex(m, idx[1]), p2 = mesh_vertex(m, idx[2]);
        vec3 e1 = v3_sub(p1, p0), e2 = v3_sub(p2, p0);
        float area = 0.5f * v3_length(v3_cross(e1, e2));
        if (!(area > 0.0f)) {
            dropped++;
            continue;
        }
        vec3 n = triangle_emit_normal(m, t);
        pn_light *l = push_light(ll, err);
        if (!l) return err->status;
        /* With "power" per pbrt-v4 shape, each triangle (or patch) has its own radiance; two
         * triangles merge into a rectangle only when their radiance is the same. */
        float k = pn_emission_area_scale(m, em, t);
        l->emit = v3_scale(em->radiance, k);
        l->two_sided = em->two_sided;
        l->kelvin = em->kelvin;
        l->kelvin_scale = em->kelvin_scale;
        l->spd = em->spd;
        l->mesh = mi;
        l->prim = (int)t;
        vec3 rp0, re1, re2;
        bool same_emit = true;
        if (em->per_shape != 0 && t + 1 < m->triangle_count) {
            float k2 = pn_emission_area_scale(m, em, t + 1);
            same_emit = fabsf(k2 - k) <= 1e-5f * fmaxf(k, k2);
        }
        if (t + 1 < m->triangle_count && same_emit &&
            pair_is_rectangle(m, t, t + 1, n, triangle_emit_normal(m, t + 1), &rp0, &re1, &re2)) {
            l->kind = PN_LIGHT_RECTANGLE;
            l->p = rp0;
            l->e1 = re1;
            l->e2 = re2;
            l->n = n;
            l->area = v3_length(v3_cross(re1, re2));
            t++;
        } else {
            l->kind = PN_LIGHT_TRIANGLE;
            l->p = p0;
            l->e1 = e1;
            l->e2 = e2;
            l->n = n;
            l->area = area;
        }
    }
    if (dropped)
        pn_warn(scene->ctx, &scene->warnings, "%s: %d zero-area emitting triangle(s) dropped",
                m->source ? m->source : "mesh", dropped);
    return PN_OK;
}

float pn_gonio_factor(const pn_lights *lights, const pn_light *l, vec3 w) {
    const pn_gonio *g = &lights->gonios[l->env];
    if (g->photo)
        return (float)(pn_photometry_eval(g->photo, mat4_apply_vector(&g->light_from_world, w)) * g->inv_peak_cd);
    if (!g->mono) return 1.0f;
    vec3 wl = v3_normalize(mat4_apply_vector(&g->light_from_world, w));
    float u, v;
    pn_equal_area_sphere_to_square(wl, &u, &v);
    int x = (int)(u * (float)g->width), y = (int)(v * (float)g->height);
    x = x < 0 ? 0 : (x >= g->width ? g->width - 1 : x);
    y = y < 0 ? 0 : (y >= g->height ? g->height - 1 : y);
    return g->mono[(size_t)y * (size_t)g->width + (size_t)x];
}

/* A goniometric light's table entry: the image as one channel, and the frame with y and z
 * swapped (pbrt-v4: render-from-light times the swap, so light-from-world is swap times it). */
static pn_status gonio_prepare(const struct pn_scene_s *scene, const pn_light_def *d, pn_gonio *g, pn_err *err) {
    mat4 swap = mat4_identity();
    swap.m[1][1] = 0.0;
    swap.m[1][2] = 1.0;
    swap.m[2][1] = 1.0;
    swap.m[2][2] = 0.0;
    g->light_from_world = mat4_mul(swap, d->light_from_world);
    g->peak = 1.0f;
    if (d->image < 0) return PN_OK;
    const pn_texture_image *img = &scene->images[d->image];
    size_t n = (size_t)img->width * (size_t)img->height;
    g->mono = malloc(n * sizeof *g->mono);
    if (!g->mono) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a goniometric image");
    for (size_t i = 0; i < n; i++) {
        g->mono[i] = (img->rgb[3 * i] + img->rgb[3 * i + 1] + img->rgb[3 * i + 2]) / 3.0f;
        if (g->mono[i] > g->peak) g->peak = g->mono[i];
    }
    g->width = img->width;
    g->height = img->height;
    return PN_OK;
}

void pn_lights_free(pn_lights *lights) {
    if (!lights) return;
    for (int i = 0; i < lights->gonio_count; i++) {
        free(lights->gonios[i].mono);
        if (lights->gonios[i].owns_dist) pn_distribution2d_free(lights->gonios[i].dist);
    }
    free(lights->gonios);
    for (int i = 0; i < lights->projection_count; i++) pn_distribution2d_free(lights->projections[i].dist);
    free(lights->projections);
    for (int i = 0; i < lights->env_count; i++) pn_distribution2d_free(lights->envs[i].dist);
    free(lights->envs);
    free(lights->lights);
    pn_lights_free_soa(lights);
    free(lights);
}

pn_status pn_lights_build(struct pn_scene_s *scene, pn_lights **out, pn_err *err) {
    *out = NULL;
    pn_lights *L = calloc(1, sizeof *L);
    if (!L) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    light_list ll = {0};
    pn_status st = PN_OK;
    vec3 ext = v3_sub(scene->bounds_max, scene->bounds_min);
    L->scene_center = v3_scale(v3_add(scene->bounds_max, scene->bounds_min), 0.5f);
    L->scene_radius = 0.5f * v3_length(ext);
    if (!(L->scene_radius > 0.0f) || !isfinite(L->scene_radius)) L->scene_radius = 1.0f;

    int env_defs = 0;
    for (int i = 0; i < scene->light_def_count; i++)
        if (scene->light_defs[i].kind == PN_LIGHTDEF_INFINITE) env_defs++;
    if (env_defs) {
        L->envs = calloc((size_t)env_defs, sizeof *L->envs);
        if (!L->envs) st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    int gonio_defs = 0;
    for (int i = 0; i < scene->light_def_count; i++)
        if (scene->light_defs[i].kind == PN_LIGHTDEF_GONIOMETRIC) gonio_defs++;
    if (gonio_defs && st == PN_OK) {
        L->gonios = calloc((size_t)gonio_defs, sizeof *L->gonios);
        if (!L->gonios) st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    int projection_defs = 0;
    for (int i = 0; i < scene->light_def_count; i++)
        if (scene->light_defs[i].kind == PN_LIGHTDEF_PROJECTION) projection_defs++;
    if (projection_defs && st == PN_OK) {
        L->projections = calloc((size_t)projection_defs, sizeof *L->projections);
        if (!L->projections) st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    for (int i = 0; st == PN_OK && i < scene->light_def_count; i++) {
        const pn_light_def *d = &scene->light_defs[i];
        if (d->kind != PN_LIGHTDEF_INFINITE && v3_max_component(d->intensity) <= 0.0f) {
            pn_warn(scene->ctx, &scene->warnings, "%s: light with zero power dropped",
                    d->source ? d->source : "LightSource");
            continue;
        }
        pn_light *l = push_light(&ll, err);
        if (!l) {
            st = err->status;
            break;
        }
        if (d->kelvin > 0.0f && d->kind != PN_LIGHTDEF_INFINITE && d->kind != PN_LIGHTDEF_PROJECTION) {
            l->kelvin = d->kelvin;
            l->kelvin_scale = (float)pn_blackbody_unit_scale(d->kelvin);
        }
        if (d->kind != PN_LIGHTDEF_INFINITE && d->kind != PN_LIGHTDEF_PROJECTION) l->spd = d->spd;
        switch (d->kind) {
        case PN_LIGHTDEF_POINT:
            l->kind = PN_LIGHT_POINT;
            l->p = d->position;
            l->emit = d->intensity;
            break;
        case PN_LIGHTDEF_GONIOMETRIC:
            l->kind = PN_LIGHT_GONIOMETRIC;
            l->p = d->position;
            l->emit = d->intensity;
            l->env = L->gonio_count;
            if (d->photometry >= 0) {
                pn_gonio *g = &L->gonios[L->gonio_count];
                st = pn_gonio_prepare_photometric(scene, d, g, L->gonios, L->gonio_count, err);
                /* A luminaire dark beyond gamma_max: its cone in the record (axis n, cosine in
                 * cos_total_width, as a spot's), so that ias culls it exactly outside; image
                 * lights keep n = 0 (no cone). */
                if (st == PN_OK && g->rigid && g->cos_max_gamma > -1.0f) {
                    l->n = g->nadir;
                    l->cos_total_width = g->cos_max_gamma - 1e-5f;
                }
            } else
                st = gonio_prepare(scene, d, &L->gonios[L->gonio_count], err);
            L->gonio_count++;
            break;
        case PN_LIGHTDEF_PROJECTION: {
            pn_projection *pr = &L->projections[L->projection_count];
            l->env = L->projection_count++;
            st = pn_projection_prepare(scene, d, pr, l, err);
            if (st == PN_OK && !(l->power > 0.0f)) {
                pn_warn(scene->ctx, &scene->warnings, "%s: projection light with a black image dropped",
                        d->source ? d->source : "LightSource");
                ll.count--;
            }
            break;
        }
        case PN_LIGHTDEF_SPOT:
            l->kind = PN_LIGHT_SPOT;
            l->p = d->position;
            l->n = v3_normalize(d->direction);
            l->emit = d->intensity;
            l->cos_falloff_start = d->cos_falloff_start;
            l->cos_total_width = d->cos_total_width;
            break;
        case PN_LIGHTDEF_DISTANT:
            l->kind = PN_LIGHT_DISTANT;
            l->n = v3_normalize(d->direction);
            l->emit = d->intensity;
            break;
        case PN_LIGHTDEF_INFINITE: {
            pn_env *env = &L->envs[L->env_count];
            memset(env, 0, sizeof *env);
            env->world_from_light = d->world_from_light;
            env->light_from_world = d->light_from_world;
            env->equal_area = d->equal_area;
            if (d->image >= 0 && d->image < scene->image_count) {
                const pn_texture_image *img = &scene->images[d->image];
                env->width = img->width;
                env->height = img->height;
                env->rgb = img->rgb;
                env->scale = d->intensity;
            } else {
                env->constant = d->intensity;
            }
            st = env_prepare(env, err);
            if (st != PN_OK) break;
            if (env->average_luminance <= 0.0f) {
                pn_warn(scene->ctx, &scene->warnings, "%s: environment light with zero power dropped",
                        d->source ? d->source : "LightSource");
                pn_distribution2d_free(env->dist);
                env->dist = NULL;
                ll.count--;
                break;
            }
            l->kind = PN_LIGHT_ENVIRONMENT;
            l->env = L->env_count++;
            l->emit = env->rgb ? env->scale : env->constant;
            break;
        }
        }
    }
    for (int mi = 0; st == PN_OK && mi < scene->mesh_count; mi++) {
        const pn_mesh *m = &scene->meshes[mi];
        if (m->emission < 0 || m->object >= 0) continue;
        if (v3_max_component(scene->emissions[m->emission].radiance) <= 0.0f) continue;
        if (is_interface(scene, m->material)) {
            pn_warn(scene->ctx, &scene->warnings,
                    "%s: area light on a shape with the \"interface\" material ignored (as pbrt-v4 does)",
                    m->source ? m->source : "mesh");
            continue;
        }
        st = add_mesh_lights(scene, mi, &ll, err);
    }
    for (int si = 0; st == PN_OK && si < scene->sphere_count; si++) {
        const pn_sphere *s = &scene->spheres[si];
        if (s->emission < 0 || s->object >= 0) continue;
        if (v3_max_component(scene->emissions[s->emission].radiance) <= 0.0f) continue;
        if (is_interface(scene, s->material)) {
            pn_warn(scene->ctx, &scene->warnings,
                    "sphere light %d: area light on a shape with the \"interface\" material ignored (as pbrt-v4 does)",
                    si);
            continue;
        }
        if (s->flip_normals) {
            pn_warn(scene->ctx, &scene->warnings, "%s: sphere light %d emits inwards; it is not sampled",
                    s->source ? s->source : "?:0:0", si);
            continue;
        }
        pn_light *l = push_light(&ll, err);
        if (!l) {
            st = err->status;
            break;
        }
        l->kind = PN_LIGHT_SPHERE;
        l->p = s->center;
        l->radius = s->radius;
        l->area = 4.0f * PN_PI * s->radius * s->radius;
        l->emit = scene->emissions[s->emission].radiance;
        l->two_sided = false;
        l->kelvin = scene->emissions[s->emission].kelvin;
        l->kelvin_scale = scene->emissions[s->emission].kelvin_scale;
        l->spd = scene->emissions[s->emission].spd;
    }
    if (st != PN_OK) {
        free(ll.items);
        pn_lights_free(L);
        return st;
    }
    L->lights = ll.items;
    L->count = ll.count;
    for (int i = 0; i < L->count; i++) L->count_by_kind[L->lights[i].kind]++;
    st = pn_lights_build_soa(L, err);
    if (st != PN_OK) {
        pn_lights_free(L);
        return st;
    }
    *out = L;
    return PN_OK;
}

/* ---- emission seen by eye rays ------------------------------------------------------------ */

vec3 pn_emission_radiance(const struct pn_scene_s *scene, int emission, vec3 ng, vec3 w) {
    if (emission < 0 || emission >= scene->emission_count) return v3(0, 0, 0);
    const pn_emission *e = &scene->emissions[emission];
    if (!e->two_sided && v3_dot(ng, w) <= 0.0f) return v3(0, 0, 0);
    return e->radiance;
}

vec3 pn_hit_emission(const struct pn_scene_s *scene, const pn_hit *hit, vec3 w) {
    if (hit->emission < 0 || hit->emission >= scene->emission_count) return v3(0, 0, 0);
    vec3 le = pn_emission_radiance(scene, hit->emission, hit->ng, w);
    const pn_emission *e = &scene->emissions[hit->emission];
    if (e->per_shape != 0 && hit->mesh >= 0 && hit->mesh < scene->mesh_count)
        le = v3_scale(le, pn_emission_area_scale(&scene->meshes[hit->mesh], e, hit->prim));
    return le;
}

vec3 pn_light_radiance_spectral(const pn_lights *lights, const pn_light *l, vec3 rgb, const pn_swl *wl) {
    (void)lights;
    if (l->spd && pn_swl_active(wl)) return pn_swl_tabulated(wl, l->spd, rgb);
    if (l->kelvin > 0.0f) return pn_swl_blackbody(wl, l->kelvin, l->kelvin_scale, rgb);
    return pn_swl_illuminant(wl, rgb);
}

vec3 pn_hit_emission_spectral(const struct pn_scene_s *scene, const pn_hit *hit, vec3 w, const pn_swl *wl) {
    vec3 le = pn_hit_emission(scene, hit, w);
    if (!pn_swl_active(wl) || hit->emission < 0 || hit->emission >= scene->emission_count) return le;
    const pn_emission *e = &scene->emissions[hit->emission];
    if (e->spd) return pn_swl_tabulated(wl, e->spd, le);
    if (e->kelvin > 0.0f) return pn_swl_blackbody(wl, e->kelvin, e->kelvin_scale, le);
    return pn_swl_illuminant(wl, le);
}

/* ---- unoccluded irradiance ---------------------------------------------------------------- */

float pn_polygon_irradiance(const vec3 *v, int count, vec3 n) {
    /* Clip the polygon (relative to the receiver at the origin) against the plane n.x = 0,
     * keeping the part in front (Sutherland–Hodgman with one plane). */
    vec3 clipped[32];
    int m = 0;
    if (count > 30) count = 30;
    for (int i = 0; i < count; i++) {
        vec3 a = v[i], b = v[(i + 1) % count];
        float da = v3_dot(a, n), db = v3_dot(b, n);
        if (da > 0.0f) clipped[m++] = a;
        if ((da > 0.0f) != (db > 0.0f)) {
            float t = da / (da - db);
            clipped[m++] = v3_add(a, v3_scale(v3_sub(b, a), t));
        }
    }
    if (m < 3) return 0.0f;
    /* Lambert: E = (1/2) sum_i angle(v_i, v_i+1) * (unit normal of the edge's plane) . n */
    float sum = 0.0f;
    for (int i = 0; i < m; i++) {
        vec3 a = v3_normalize(clipped[i]), b = v3_normalize(clipped[(i + 1) % m]);
        vec3 c = v3_cross(a, b);
        float cl = v3_length(c);
        if (cl <= 1e-12f) continue;
        float angle = atan2f(cl, v3_dot(a, b));
        sum += angle * v3_dot(c, n) / cl;
    }
    return 0.5f * fabsf(sum);
}

static float spot_falloff(const pn_light *l, float cos_theta) {
    if (cos_theta >= l->cos_falloff_start) return 1.0f;
    if (cos_theta <= l->cos_total_width) return 0.0f;
    float t = (cos_theta - l->cos_total_width) / (l->cos_falloff_start - l->cos_total_width);
    return t * t * (3.0f - 2.0f * t);
}

static float lum(vec3 c) {
    return fmaxf(0.0f, v3_luminance(c));
}

float pn_light_irradiance_estimate(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n) {
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_SPOT:
    case PN_LIGHT_GONIOMETRIC: {
        vec3 d = v3_sub(l->p, p);
        float d2 = v3_length2(d);
        if (!(d2 > 0.0f)) return 0.0f;
        vec3 wi = v3_scale(d, 1.0f / sqrtf(d2));
        float c = v3_dot(n, wi);
        if (c <= 0.0f) return 0.0f;
        float e = lum(l->emit) * c / d2;
        if (l->kind == PN_LIGHT_SPOT) e *= spot_falloff(l, -v3_dot(wi, l->n));
        if (l->kind == PN_LIGHT_GONIOMETRIC) e *= pn_gonio_factor(lights, l, v3_neg(wi));
        return e;
    }
    case PN_LIGHT_DISTANT: return lum(l->emit) * fmaxf(0.0f, v3_dot(n, l->n));
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK: {
        vec3 rel = v3_sub(l->p, p);
        if (!l->two_sided && v3_dot(rel, l->n) >= 0.0f) return 0.0f;
        vec3 poly[24];
        int count;
        if (l->kind == PN_LIGHT_TRIANGLE) {
            poly[0] = rel;
            poly[1] = v3_add(rel, l->e1);
            poly[2] = v3_add(rel, l->e2);
            count = 3;
        } else if (l->kind == PN_LIGHT_RECTANGLE) {
            poly[0] = rel;
            poly[1] = v3_add(rel, l->e1);
            poly[2] = v3_add(rel, v3_add(l->e1, l->e2));
            poly[3] = v3_add(rel, l->e2);
            count = 4;
        } else {
            vec3 t, b;
            v3_basis(l->n, &t, &b);
            count = 24;
            for (int k = 0; k < count; k++) {
                float a = 2.0f * PN_PI * (float)k / (float)count;
                poly[k] = v3_add(rel, v3_add(v3_scale(t, l->radius * cosf(a)), v3_scale(b, l->radius * sinf(a))));
            }
        }
        return lum(l->emit) * pn_polygon_irradiance(poly, count, n);
    }
    case PN_LIGHT_SPHERE: {
        vec3 d = v3_sub(l->p, p);
        float d2 = v3_length2(d);
        float r2 = l->radius * l->radius;
        if (d2 <= r2) return lum(l->emit) * PN_PI;
        float sin2 = r2 / d2, sin_a = sqrtf(sin2);
        float c = v3_dot(n, d) / sqrtf(d2);
        float ceff;
        if (c >= sin_a)
            ceff = c;
        else if (c > -sin_a)
            ceff = (c + sin_a) * (c + sin_a) / (4.0f * sin_a);
        else
            ceff = 0.0f;
        return lum(l->emit) * PN_PI * sin2 * ceff;
    }
    case PN_LIGHT_ENVIRONMENT: return env_irradiance(&lights->envs[l->env], n);
    case PN_LIGHT_PROJECTION: return pn_projection_irradiance(lights, l, p, n);
    case PN_LIGHT_KIND_COUNT: break;
    }
    return 0.0f;
}
