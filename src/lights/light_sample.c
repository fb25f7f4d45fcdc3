/* light_sample.c — sampling a point on each kind of light as seen from a receiver: solid-angle
 * sampling for rectangles (Ureña et al. 2013) and spheres (the cone they subtend), uniform area
 * for triangles and disks, importance sampling by luminance for environment maps. */
#include "lights/lights.h"

#include "core/sampling.h"

/* pbrt-v4's lower limit for spherical sampling of bilinear patches (MinSphericalSampleArea). */
#define PN_MIN_SPHERICAL_SOLID_ANGLE 3e-4f

static float spot_falloff(const pn_light *l, float cos_theta) {
    if (cos_theta >= l->cos_falloff_start) return 1.0f;
    if (cos_theta <= l->cos_total_width) return 0.0f;
    float t = (cos_theta - l->cos_total_width) / (l->cos_falloff_start - l->cos_total_width);
    return t * t * (3.0f - 2.0f * t);
}

/* The solid-angle density at p of area density 1/area, for direction wi reaching the light's
 * surface at squared distance d2; 0 where the surface is seen edge-on or from behind. */
static float area_to_solid_angle(const pn_light *l, vec3 wi, float d2) {
    float cos_l = -v3_dot(wi, l->n);
    if (l->two_sided) cos_l = fabsf(cos_l);
    if (cos_l <= 1e-7f) return 0.0f;
    float pdf = (1.0f / l->area) * d2 / cos_l;
    return isfinite(pdf) && pdf > 0.0f ? pdf : 0.0f;
}

/* Converts an area sample y (with area density 1/area) into a solid-angle sample at p. */
static bool finish_area_sample(const pn_light *l, vec3 p, vec3 y, pn_light_sample *s) {
    vec3 d = v3_sub(y, p);
    float d2 = v3_length2(d);
    if (!(d2 > 0.0f)) return false;
    float dist = sqrtf(d2);
    vec3 wi = v3_scale(d, 1.0f / dist);
    s->wi = wi;
    s->dist = dist;
    s->radiance = l->emit;
    s->pdf = area_to_solid_angle(l, wi, d2);
    s->delta = false;
    return s->pdf > 0.0f;
}

/* A rectangle seen from p (side: p's signed distance to its plane) is sampled by solid angle
 * (Ureña et al. 2013, set up in *sr) where it looks big; where it subtends less than
 * PN_MIN_SPHERICAL_SOLID_ANGLE (estimated as A cos / d^2) both densities are nearly equal and the
 * cheaper area sampling is used, as pbrt-v4 does. */
static bool rectangle_spherical(const pn_light *l, vec3 p, float side, pn_spherical_rectangle *sr) {
    vec3 to_centre = v3_sub(v3_add(l->p, v3_scale(v3_add(l->e1, l->e2), 0.5f)), p);
    float d2c = v3_length2(to_centre);
    float approx_solid_angle = l->area * fabsf(side) / (d2c * sqrtf(d2c));
    return approx_solid_angle >= PN_MIN_SPHERICAL_SOLID_ANGLE &&
           pn_spherical_rectangle_init(sr, p, l->p, l->e1, l->e2) && sr->solid_angle > 1e-6f;
}

bool pn_light_sample_point(const pn_lights *lights, const pn_light *l, vec3 p, float u1, float u2, pn_light_sample *s) {
    return pn_light_sample_point_cached(lights, l, p, u1, u2, NULL, s);
}

bool pn_light_sample_point_cached(const pn_lights *lights, const pn_light *l, vec3 p, float u1, float u2,
                                  pn_light_sample_cache *cache, pn_light_sample *s) {
    switch (l->kind) {
    case PN_LIGHT_POINT:
    case PN_LIGHT_SPOT:
    case PN_LIGHT_GONIOMETRIC: {
        vec3 d = v3_sub(l->p, p);
        float d2 = v3_length2(d);
        if (!(d2 > 0.0f)) return false;
        float dist = sqrtf(d2);
        s->wi = v3_scale(d, 1.0f / dist);
        s->dist = dist;
        float k = 1.0f / d2;
        if (l->kind == PN_LIGHT_SPOT) k *= spot_falloff(l, -v3_dot(s->wi, l->n));
        if (l->kind == PN_LIGHT_GONIOMETRIC) k *= pn_gonio_factor(lights, l, v3_neg(s->wi));
        if (k <= 0.0f) return false;
        s->radiance = v3_scale(l->emit, k);
        s->pdf = 1.0f;
        s->delta = true;
        return true;
    }
    case PN_LIGHT_DISTANT:
        s->wi = l->n;
        s->dist = INFINITY;
        s->radiance = l->emit;
        s->pdf = 1.0f;
        s->delta = true;
        return true;
    case PN_LIGHT_TRIANGLE: {
        float b0, b1;
        pn_sample_uniform_triangle(u1, u2, &b0, &b1);
        vec3 y = v3_add(l->p, v3_add(v3_scale(l->e1, b1), v3_scale(l->e2, 1.0f - b0 - b1)));
        return finish_area_sample(l, p, y, s);
    }
    case PN_LIGHT_RECTANGLE: {
        /* One-sided: nothing reaches a point behind the emitting side. */
        float side = v3_dot(v3_sub(p, l->p), l->n);
        if (!l->two_sided && side <= 0.0f) return false;
        pn_light_sample_cache local;
        pn_light_sample_cache *c = cache ? cache : &local;
        if (!cache || c->light != l || c->p.x != p.x || c->p.y != p.y || c->p.z != p.z) {
            /* The set-up depends on the light and the receiver only: several shadow rays of one
             * eye ray to the same light share it. */
            c->light = l;
            c->p = p;
            c->spherical = rectangle_spherical(l, p, side, &c->sr);
        }
        if (c->spherical) {
            const pn_spherical_rectangle sr = c->sr;
            vec3 y = pn_spherical_rectangle_sample(&sr, u1, u2);
            vec3 d = v3_sub(y, p);
            float dist = v3_length(d);
            if (!(dist > 0.0f)) return false;
            s->wi = v3_scale(d, 1.0f / dist);
            s->dist = dist;
            s->radiance = l->emit;
            s->pdf = 1.0f / sr.solid_angle;
            s->delta = false;
            return true;
        }
        vec3 y = v3_add(l->p, v3_add(v3_scale(l->e1, u1), v3_scale(l->e2, u2)));
        return finish_area_sample(l, p, y, s);
    }
    case PN_LIGHT_DISK: {
        float dx, dy;
        pn_sample_concentric_disk(u1, u2, &dx, &dy);
        vec3 t, b;
        v3_basis(l->n, &t, &b);
        vec3 y = v3_add(l->p, v3_add(v3_scale(t, dx * l->radius), v3_scale(b, dy * l->radius)));
        return finish_area_sample(l, p, y, s);
    }
    case PN_LIGHT_SPHERE: {
        vec3 y;
        float pdf;
        if (!pn_sample_sphere_from_point(l->p, l->radius, p, u1, u2, &y, &pdf)) return false;
        vec3 d = v3_sub(y, p);
        float dist = v3_length(d);
        if (!(dist > 0.0f) || !(pdf > 0.0f)) return false;
        s->wi = v3_scale(d, 1.0f / dist);
        s->dist = dist;
        s->radiance = l->emit;
        s->pdf = pdf;
        s->delta = false;
        return true;
    }
    case PN_LIGHT_ENVIRONMENT: {
        const pn_env *env = &lights->envs[l->env];
        vec3 wl;
        float pdf;
        if (!env->dist) {
            /* Constant environment: uniform directions over the sphere. */
            wl = pn_sample_uniform_sphere(u1, u2);
            pdf = PN_INV_4PI;
            s->radiance = env->constant;
        } else {
            float uv_pdf, u, v;
            if (!pn_distribution2d_sample(env->dist, u1, u2, &u, &v, &uv_pdf)) return false;
            if (env->equal_area) {
                wl = pn_equal_area_square_to_sphere(u, v);
            } else {
                float theta = v * PN_PI, phi = u * 2.0f * PN_PI;
                float st = sinf(theta);
                if (st <= 0.0f) return false;
                wl = v3(st * cosf(phi), st * sinf(phi), cosf(theta));
            }
            /* Radiance and density both from the texel the direction maps back to, as an eye
             * ray leaving in that direction would see it: near a texel edge, float rounding may
             * put the direction in the neighbour of the texel that was sampled. */
            float lu, lv;
            s->radiance = pn_env_lookup(env, wl, &lu, &lv);
            uv_pdf = pn_distribution2d_pdf(env->dist, lu, lv);
            if (env->equal_area) {
                pdf = uv_pdf * PN_INV_4PI;
            } else {
                float st = sqrtf(wl.x * wl.x + wl.y * wl.y);
                if (st <= 0.0f) return false;
                pdf = uv_pdf / (2.0f * PN_PI * PN_PI * st);
            }
        }
        s->wi = v3_normalize(mat4_apply_vector(&env->world_from_light, wl));
        s->dist = INFINITY;
        s->pdf = pdf;
        s->delta = false;
        return pdf > 0.0f && isfinite(pdf);
    }
    case PN_LIGHT_PROJECTION: return pn_projection_sample_li(lights, l, p, s);
    case PN_LIGHT_KIND_COUNT: break;
    }
    return false;
}

float pn_light_pdf_direction(const pn_light *l, vec3 p, vec3 wi, float dist) {
    switch (l->kind) {
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_DISK: return area_to_solid_angle(l, wi, dist * dist);
    case PN_LIGHT_RECTANGLE: {
        float side = v3_dot(v3_sub(p, l->p), l->n);
        if (!l->two_sided && side <= 0.0f) return 0.0f;
        pn_spherical_rectangle sr;
        return rectangle_spherical(l, p, side, &sr) ? 1.0f / sr.solid_angle : area_to_solid_angle(l, wi, dist * dist);
    }
    case PN_LIGHT_SPHERE: return pn_sphere_cone_pdf(l->p, l->radius, p);
    default: return 0.0f;
    }
}
