/* vpl.c — VPL tracing (instant radiosity) and the contribution of one VPL to one receiving point
 * (IlluminationCut eq. 1, with the clamping of §4). See vpl.h for the kinds and departures.
 *
 * Light path i: a light chosen in proportion to its luminous power, a start point and direction
 * on it, then bounces; the path's power is (light power / choice probability) and is divided by
 * the number of paths at the end, so the VPLs of all paths together estimate the light leaving
 * the lights and every surface once (up to max_depth bounces).
 *
 * Direct light only (options->direct_only): the lights themselves, as Lightcuts (Walter et al.
 * 2005, §3) converts them: point, spot and goniometric lights are omni VPLs and distant lights
 * directional VPLs, exactly (as in the global-illumination set); every area light becomes
 * oriented VPLs at points on it and every environment map directional VPLs, a stratified set
 * of n_i = B p_i points per light (B the VPLs left after the exact ones, p_i the light's share
 * of the sampled lights' power), rounded up or down at random so that E[n_i] = B p_i. Each point
 * carries power_i / n_i (power_i / (B p_i) when B p_i < 1, where n_i is 0 or 1), so the set's
 * light is an unbiased estimate of the lights' (per realisation exact in total power for every
 * light with B p_i >= 1), and the strata (a shifted Hammersley set per light) keep the variance
 * of the points' positions well below that of independent choices. */
#include "lights/vpl.h"

#include "core/clock.h"
#include "core/optics.h"
#include "core/rng.h"
#include "core/sampling.h"
#include "scene/photometry.h"
#include "scene/scene.h"
#include "shade/bsdf.h"

#include <stdlib.h>
#include <string.h>

static float spot_falloff(const pn_light *l, float cos_theta) {
    if (cos_theta >= l->cos_falloff_start) return 1.0f;
    if (cos_theta <= l->cos_total_width) return 0.0f;
    float t = (cos_theta - l->cos_total_width) / (l->cos_falloff_start - l->cos_total_width);
    return t * t * (3.0f - 2.0f * t);
}

/* Growable VPL array. */
typedef struct vpl_buf {
    pn_vpl *v;
    uint32_t count, capacity;
    uint8_t *scaled; /* 1 for path VPLs (divided by the path count at the end) */
} vpl_buf;

static bool buf_push(vpl_buf *b, pn_vpl v, bool scaled) {
    if (b->count == b->capacity) {
        uint32_t cap = b->capacity ? b->capacity * 2u : 1024u;
        pn_vpl *nv = realloc(b->v, (size_t)cap * sizeof *nv);
        if (!nv) return false;
        b->v = nv;
        uint8_t *ns = realloc(b->scaled, cap);
        if (!ns) return false;
        b->scaled = ns;
        b->capacity = cap;
    }
    b->scaled[b->count] = scaled ? 1 : 0;
    b->v[b->count++] = v;
    return true;
}

/* Integral of the environment radiance over the sphere (RGB), from a fixed stratified set of
 * directions: used only for choosing lights, so its accuracy matters little. */
static vec3 env_integral(const pn_lights *L, const pn_light *l) {
    const pn_env *env = &L->envs[l->env];
    vec3 sum = v3(0, 0, 0);
    const int n = 64;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            vec3 d = pn_sample_uniform_sphere(((float)i + 0.5f) / (float)n, ((float)j + 0.5f) / (float)n);
            sum = v3_add(sum, pn_env_radiance(env, d));
        }
    return v3_scale(sum, 4.0f * PN_PI / (float)(n * n));
}

/* Power (RGB) that leaves light l, for path starts. Distant and environment lights: through a
 * disk of the scene radius. */
static vec3 light_power(const pn_lights *L, const pn_light *l) {
    float R = L->scene_radius;
    switch (l->kind) {
    case PN_LIGHT_POINT: return v3_scale(l->emit, 4.0f * PN_PI);
    case PN_LIGHT_GONIOMETRIC:
        /* A measured luminaire: its lumens (emit carries the peak candela, lights/photometric.c). */
        if (L->gonios[l->env].photo)
            return v3_scale(l->emit, (float)(L->gonios[l->env].photo->lumens * L->gonios[l->env].inv_peak_cd));
        return v3_scale(l->emit, 4.0f * PN_PI);
    case PN_LIGHT_SPOT: return v3_scale(l->emit, 2.0f * PN_PI * (1.0f - l->cos_total_width));
    case PN_LIGHT_TRIANGLE:
    case PN_LIGHT_RECTANGLE:
    case PN_LIGHT_DISK: return v3_scale(l->emit, PN_PI * l->area * (l->two_sided ? 2.0f : 1.0f));
    case PN_LIGHT_SPHERE: return v3_scale(l->emit, PN_PI * 4.0f * PN_PI * l->radius * l->radius);
    case PN_LIGHT_DISTANT: return v3_scale(l->emit, PN_PI * R * R);
    case PN_LIGHT_ENVIRONMENT: return v3_scale(env_integral(L, l), PN_PI * R * R);
    case PN_LIGHT_PROJECTION: return v3_mul(l->emit, L->projections[l->env].phi);
    default: return v3(0, 0, 0);
    }
}

static vec3 frame_dir(vec3 n, vec3 local) {
    vec3 t, b;
    v3_basis(n, &t, &b);
    return v3_add(v3_add(v3_scale(t, local.x), v3_scale(b, local.y)), v3_scale(n, local.z));
}

/* A uniform point on an area light and its emitting normal. */
static void sample_area(const pn_light *l, float u1, float u2, vec3 *p, vec3 *n) {
    switch (l->kind) {
    case PN_LIGHT_TRIANGLE: {
        float b0, b1;
        pn_sample_uniform_triangle(u1, u2, &b0, &b1);
        float b2 = 1.0f - b0 - b1;
        /* barycentrics (b0, b1, b2) of p0, p1 = p0 + e1, p2 = p0 + e2 */
        *p = v3_add(l->p, v3_add(v3_scale(l->e1, b1), v3_scale(l->e2, b2)));
        *n = l->n;
        break;
    }
    case PN_LIGHT_RECTANGLE:
        *p = v3_add(l->p, v3_add(v3_scale(l->e1, u1), v3_scale(l->e2, u2)));
        *n = l->n;
        break;
    case PN_LIGHT_DISK: {
        float x, y;
        pn_sample_concentric_disk(u1, u2, &x, &y);
        *p = v3_add(l->p, frame_dir(l->n, v3(x * l->radius, y * l->radius, 0.0f)));
        *n = l->n;
        break;
    }
    default: { /* sphere */
        vec3 d = pn_sample_uniform_sphere(u1, u2);
        *p = v3_madd(l->p, d, l->radius);
        *n = d;
        break;
    }
    }
}

/* Bits of i reversed, as a fraction in [0, 1) (the base-2 radical inverse, 24 bits). */
static float radical_inverse2(uint32_t i) {
    i = (i << 16) | (i >> 16);
    i = ((i & 0x00ff00ffu) << 8) | ((i & 0xff00ff00u) >> 8);
    i = ((i & 0x0f0f0f0fu) << 4) | ((i & 0xf0f0f0f0u) >> 4);
    i = ((i & 0x33333333u) << 2) | ((i & 0xccccccccu) >> 2);
    i = ((i & 0x55555555u) << 1) | ((i & 0xaaaaaaaau) >> 1);
    return (float)(i >> 8) * 0x1p-24f;
}

static float frac_shift(float u, float shift) {
    float v = u + shift;
    return v >= 1.0f ? v - 1.0f : v;
}

/* Direct light only (see the header comment): the sampled VPLs of area lights and environment
 * maps; budget is the number wanted beyond the exact lights. *samples receives the points drawn
 * (the "paths" of this set). Returns false when out of memory. */
static bool direct_samples(const pn_lights *L, const vec3 *power, uint32_t budget, uint64_t seed, vpl_buf *buf,
                           uint32_t *samples) {
    int n = L->count;
    double total = 0.0;
    for (int i = 0; i < n; i++) {
        const pn_light *l = &L->lights[i];
        bool sampled = l->kind == PN_LIGHT_TRIANGLE || l->kind == PN_LIGHT_RECTANGLE || l->kind == PN_LIGHT_DISK ||
                       l->kind == PN_LIGHT_SPHERE || l->kind == PN_LIGHT_ENVIRONMENT;
        float y = fmaxf(0.0f, v3_luminance(power[i]));
        if (sampled && isfinite(y)) total += (double)y;
    }
    *samples = 0;
    if (!(total > 0.0) || budget == 0) return true;
    for (int i = 0; i < n; i++) {
        const pn_light *l = &L->lights[i];
        bool area = l->kind == PN_LIGHT_TRIANGLE || l->kind == PN_LIGHT_RECTANGLE || l->kind == PN_LIGHT_DISK ||
                    l->kind == PN_LIGHT_SPHERE;
        if (!area && l->kind != PN_LIGHT_ENVIRONMENT) continue;
        float y = fmaxf(0.0f, v3_luminance(power[i]));
        if (!(y > 0.0f) || !isfinite(y)) continue;
        pn_rng rng;
        pn_rng_seed(&rng, pn_hash64(seed ^ UINT64_C(0x6469726563742d31)), (uint64_t)i);
        double expected = (double)budget * (double)y / total;
        uint32_t count = (uint32_t)floor(expected + (double)pn_rng_float(&rng));
        if (count == 0) continue;
        /* The weight of one point: 1 / n_i, or 1 / E[n_i] where n_i is 0 or 1. */
        float weight = expected >= 1.0 ? 1.0f / (float)count : (float)(1.0 / expected);
        float shift1 = pn_rng_float(&rng), shift2 = pn_rng_float(&rng);
        uint32_t side0 = pn_rng_u32(&rng) & 1u;
        for (uint32_t j = 0; j < count; j++) {
            float u1 = ((float)j + shift1) / (float)count;
            if (!(u1 < 1.0f)) u1 = 0x1.fffffep-1f;
            float u2 = frac_shift(radical_inverse2(j), shift2);
            pn_vpl v;
            if (area) {
                vec3 p, nn;
                sample_area(l, u1, u2, &p, &nn);
                /* Two-sided: the sides alternate, each carrying the power of both halves. */
                if (l->two_sided && ((j + side0) & 1u)) nn = v3_neg(nn);
                /* power_i / pi is the intensity along the normal of the whole light. */
                v = (pn_vpl){p, nn, v3_scale(power[i], PN_INV_PI * weight), PN_VPL_ORIENTED, i};
            } else {
                vec3 w = pn_sample_uniform_sphere(u1, u2);
                vec3 le = pn_env_radiance(&L->envs[l->env], w);
                if (v3_is_zero(le)) continue;
                /* The irradiance of a direction sampled with density 1 / (4 pi). */
                v = (pn_vpl){w, v3(0, 0, 0), v3_scale(le, 4.0f * PN_PI * weight), PN_VPL_DIRECTIONAL, -1};
            }
            if (!buf_push(buf, v, false)) return false;
        }
        *samples += count;
    }
    return true;
}

typedef struct tracer {
    const struct pn_scene_s *scene;
    const pn_lights *L;
    const pn_accel *accel;
    uint32_t max_depth;
    vpl_buf *buf;
} tracer;

/* Follows a light path from o along unit d with power beta, leaving a VPL at every diffuse or
 * glossy hit (bounce 1..max_depth). */
static bool trace_bounces(const tracer *t, pn_rng *rng, vec3 o, vec3 d, vec3 beta) {
    for (uint32_t depth = 1; depth <= t->max_depth; depth++) {
        pn_hit hit;
        if (!pn_accel_intersect(t->accel, o, d, 0.0f, INFINITY, &hit)) return true;
        vec3 wo = v3_neg(d);
        pn_bsdf b;
        pn_bsdf_at(t->scene, &hit, wo, &b);
        float eps = pn_accel_ray_epsilon(t->accel, hit.p);
        if (b.kind == PN_MATERIAL_LAMBERT_BLINN) {
            if (v3_is_zero(b.kd)) return true;
            pn_vpl v = {hit.p, b.ns, v3_scale(v3_mul(beta, b.kd), PN_INV_PI), PN_VPL_ORIENTED, -1};
            if (!buf_push(t->buf, v, true)) return false;
            float q = fminf(1.0f, v3_max_component(b.kd));
            if (pn_rng_float(rng) >= q) return true;
            beta = v3_scale(v3_mul(beta, b.kd), 1.0f / q);
            float u1 = pn_rng_float(rng), u2 = pn_rng_float(rng);
            d = v3_normalize(frame_dir(b.ns, pn_sample_cosine_hemisphere(u1, u2)));
            if (v3_dot(d, b.ng) <= 0.0f) return true;
            o = v3_madd(hit.p, b.ng, eps);
        } else if (b.kind == PN_MATERIAL_MIRROR) {
            beta = v3_mul(beta, b.specular);
            d = v3_normalize(pn_reflect(wo, b.ns));
            o = v3_madd(hit.p, b.ng, eps);
        } else if (b.kind == PN_MATERIAL_DIELECTRIC) {
            float eta = b.entering ? b.eta : 1.0f / b.eta;
            float F = pn_fresnel_dielectric(v3_dot(wo, b.ns), eta);
            vec3 wt;
            if (!pn_refract(wo, b.ns, eta, &wt) || pn_rng_float(rng) < F) {
                d = v3_normalize(pn_reflect(wo, b.ns));
                o = v3_madd(hit.p, b.ng, eps);
            } else {
                d = v3_normalize(wt);
                o = v3_madd(hit.p, b.ng, -eps);
            }
            beta = v3_mul(beta, b.specular);
        } else {
            return true;
        }
        if (v3_is_zero(beta)) return true;
    }
    return true;
}

pn_status pn_vpl_trace(const struct pn_scene_s *scene, const pn_lights *L, const pn_accel *accel,
                       const pn_vpl_settings *s, pn_vpl_set *out, pn_err *err) {
    return pn_vpl_trace_with(scene, L, accel, s, NULL, out, err);
}

pn_status pn_vpl_trace_with(const struct pn_scene_s *scene, const pn_lights *L, const pn_accel *accel,
                            const pn_vpl_settings *s, const pn_vpl_trace_options *options, pn_vpl_set *out,
                            pn_err *err) {
    static const pn_vpl_trace_options none = {0};
    const pn_vpl_trace_options *opt = options ? options : &none;
    memset(out, 0, sizeof *out);
    double t0 = pn_clock_seconds();
    out->clamp_distance = s->clamp_fraction * L->scene_radius;
    out->min_dist2 = out->clamp_distance * out->clamp_distance;
    vpl_buf buf = {0};
    tracer t = {scene, L, accel, s->max_depth, &buf};
    int n = L->count;
    double *cdf = calloc((size_t)n + 1, sizeof *cdf);
    vec3 *power = calloc((size_t)n + 1, sizeof *power);
    if (!cdf || !power) goto oom;
    if (opt->progress && !opt->progress(opt->progress_user, 0.0)) goto cancelled;
    /* The exact lights: point, spot, goniometric, projection (omni) and distant (directional). */
    for (int i = 0; i < n; i++) {
        const pn_light *l = &L->lights[i];
        if (l->kind == PN_LIGHT_POINT || l->kind == PN_LIGHT_SPOT || l->kind == PN_LIGHT_GONIOMETRIC) {
            /* A goniometric image may exceed 1: its VPL carries emit * peak and the factor
             * relative to the peak (pn_vpl_contribution_with), so that the cuts' bound M_max G_max
             * I holds as for a point light. peak is 1 for images within [0, 1]: same floats. */
            float peak = l->kind == PN_LIGHT_GONIOMETRIC ? L->gonios[l->env].peak : 1.0f;
            pn_vpl v = {l->p, l->kind == PN_LIGHT_SPOT ? l->n : v3(0, 0, 0), v3_scale(l->emit, peak), PN_VPL_OMNI, i};
            if (!buf_push(&buf, v, false)) goto oom;
        } else if (l->kind == PN_LIGHT_DISTANT) {
            pn_vpl v = {v3_normalize(l->n), v3(0, 0, 0), l->emit, PN_VPL_DIRECTIONAL, -1};
            if (!buf_push(&buf, v, false)) goto oom;
        } else if (l->kind == PN_LIGHT_PROJECTION) {
            /* The VPL's intensity is emit times the image's largest channel, and its factor
             * towards a receiver the pixel divided by it (<= 1 per channel): the cuts' bound
             * M_max G_max I (shade/bounds.c) then bounds it as it bounds a point light. */
            pn_vpl v = {l->p, l->n, v3_scale(l->emit, L->projections[l->env].peak), PN_VPL_OMNI, i};
            if (!buf_push(&buf, v, false)) goto oom;
        }
        power[i] = light_power(L, l);
        float y = fmaxf(0.0f, v3_luminance(power[i]));
        cdf[i + 1] = cdf[i] + (isfinite(y) ? (double)y : 0.0);
    }
    double total = cdf[n];
    uint32_t paths = 0;
    const uint32_t exact = buf.count;
    if (opt->direct_only) {
        if (!direct_samples(L, power, s->count > exact ? s->count - exact : 0, s->seed, &buf, &paths)) goto oom;
    } else if (total > 0.0 && s->count > exact) {
        /* A path may leave no VPL (it escapes, or hits black): stop after many empty paths. */
        const uint64_t max_paths = (uint64_t)s->count * 64u + 4096u;
        float R = L->scene_radius;
        while (buf.count < s->count && paths < max_paths) {
            /* Light that reaches nothing (an open scene, black surfaces): give up early. */
            if (paths >= 65536 && buf.count == exact) break;
            if ((paths & 4095u) == 0 && opt->progress &&
                !opt->progress(opt->progress_user, (double)buf.count / (double)s->count))
                goto cancelled;
            pn_rng rng;
            pn_rng_seed(&rng, pn_hash64(s->seed ^ UINT64_C(0x5bd1e995)), paths);
            paths++;
            double target = (double)pn_rng_float(&rng) * total;
            int lo = 0, hi = n;
            while (hi - lo > 1) {
                int mid = (lo + hi) / 2;
                if (cdf[mid] <= target)
                    lo = mid;
                else
                    hi = mid;
            }
            while (lo < n - 1 && cdf[lo + 1] - cdf[lo] <= 0.0) lo++;
            const pn_light *l = &L->lights[lo];
            float prob = (float)((cdf[lo + 1] - cdf[lo]) / total);
            if (!(prob > 0.0f)) continue;
            vec3 beta = v3_scale(power[lo], 1.0f / prob);
            float u1 = pn_rng_float(&rng), u2 = pn_rng_float(&rng);
            vec3 o, d;
            switch (l->kind) {
            case PN_LIGHT_GONIOMETRIC:
                if (L->gonios[l->env].photo) {
                    /* A measured luminaire: directions by its intensity (lights/photometric.c);
                     * the path carries I(d) / (pdf(d) prob). */
                    float pdf;
                    if (!pn_gonio_sample_direction(L, l, u1, u2, &d, &pdf)) continue;
                    o = l->p;
                    beta = v3_scale(l->emit, pn_gonio_factor(L, l, d) / (pdf * prob));
                    break;
                }
                /* fall through */
            case PN_LIGHT_POINT:
                o = l->p;
                d = pn_sample_uniform_sphere(u1, u2);
                if (l->kind == PN_LIGHT_GONIOMETRIC) beta = v3_scale(beta, pn_gonio_factor(L, l, d));
                break;
            case PN_LIGHT_SPOT: {
                float c = 1.0f - u1 * (1.0f - l->cos_total_width);
                float sn = sqrtf(fmaxf(0.0f, 1.0f - c * c)), phi = 2.0f * PN_PI * u2;
                d = v3_normalize(frame_dir(l->n, v3(sn * cosf(phi), sn * sinf(phi), c)));
                o = l->p;
                beta = v3_scale(beta, spot_falloff(l, c));
                break;
            }
            case PN_LIGHT_PROJECTION: {
                /* A direction by the image's intensity (lights/projection.c); the path carries
                 * I(d) / (pdf(d) prob), whose mean over d is the light's power / prob. */
                float pdf;
                if (!pn_projection_sample_direction(L, l, u1, u2, &d, &pdf)) continue;
                o = l->p;
                beta = v3_scale(v3_mul(l->emit, pn_projection_factor(L, l, d)), 1.0f / (pdf * prob));
                break;
            }
            case PN_LIGHT_TRIANGLE:
            case PN_LIGHT_RECTANGLE:
            case PN_LIGHT_DISK:
            case PN_LIGHT_SPHERE: {
                vec3 nn;
                sample_area(l, u1, u2, &o, &nn);
                if (l->two_sided && pn_rng_float(&rng) < 0.5f) nn = v3_neg(nn);
                /* The start point is an oriented VPL: a Lambertian emitter of power beta has
                 * intensity beta / pi along its normal. */
                pn_vpl v = {o, nn, v3_scale(beta, PN_INV_PI), PN_VPL_ORIENTED, lo};
                if (!buf_push(&buf, v, true)) goto oom;
                float w1 = pn_rng_float(&rng), w2 = pn_rng_float(&rng);
                d = v3_normalize(frame_dir(nn, pn_sample_cosine_hemisphere(w1, w2)));
                o = v3_madd(o, nn, pn_accel_ray_epsilon(accel, o));
                break;
            }
            case PN_LIGHT_DISTANT:
            case PN_LIGHT_ENVIRONMENT: {
                vec3 w; /* towards the light */
                if (l->kind == PN_LIGHT_DISTANT) {
                    w = v3_normalize(l->n);
                } else {
                    w = pn_sample_uniform_sphere(u1, u2);
                    vec3 le = pn_env_radiance(&L->envs[l->env], w);
                    /* beta = L(w) 4 pi (pi R^2) / prob; the directional VPL's irradiance is
                     * beta / (pi R^2). */
                    beta = v3_scale(le, 4.0f * PN_PI * PN_PI * R * R / prob);
                    pn_vpl v = {w, v3(0, 0, 0), v3_scale(le, 4.0f * PN_PI / prob), PN_VPL_DIRECTIONAL, -1};
                    if (!v3_is_zero(le) && !buf_push(&buf, v, true)) goto oom;
                }
                float x, y;
                pn_sample_concentric_disk(pn_rng_float(&rng), pn_rng_float(&rng), &x, &y);
                o = v3_add(v3_madd(L->scene_center, w, 1.01f * R), frame_dir(w, v3(x * R, y * R, 0.0f)));
                d = v3_neg(w);
                break;
            }
            default: continue;
            }
            if (v3_is_zero(beta) || !v3_is_finite(beta)) continue;
            if (!trace_bounces(&t, &rng, o, d, beta)) goto oom;
        }
    }
    /* Path VPLs carry the power of one path: divide by the number of paths. */
    if (paths > 0) {
        float inv = 1.0f / (float)paths;
        for (uint32_t i = 0; i < buf.count; i++)
            if (buf.scaled[i]) buf.v[i].intensity = v3_scale(buf.v[i].intensity, inv);
    }
    /* Drop VPLs that carry nothing (or non-finite values). */
    uint32_t m = 0;
    for (uint32_t i = 0; i < buf.count; i++) {
        pn_vpl v = buf.v[i];
        if (!v3_is_finite(v.intensity) || !(v3_luminance(v.intensity) > 0.0f)) continue;
        buf.v[m++] = v;
        out->count_by_kind[v.kind]++;
    }
    free(buf.scaled);
    free(cdf);
    free(power);
    out->vpls = buf.v;
    out->count = m;
    out->paths = paths;
    out->seconds = pn_clock_seconds() - t0;
    if (opt->progress) opt->progress(opt->progress_user, 1.0);
    return PN_OK;
cancelled:
    free(buf.v);
    free(buf.scaled);
    free(cdf);
    free(power);
    memset(out, 0, sizeof *out);
    return pn_err_set(err, PN_ERROR_CANCELLED, "render cancelled while tracing VPLs");
oom:
    free(buf.v);
    free(buf.scaled);
    free(cdf);
    free(power);
    memset(out, 0, sizeof *out);
    return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory tracing VPLs");
}

void pn_vpl_set_free(pn_vpl_set *set) {
    if (!set) return;
    free(set->vpls);
    memset(set, 0, sizeof *set);
}

vec3 pn_vpl_receiver_brdf_cos(const pn_vpl_receiver *r, vec3 wi) {
    return pn_vpl_brdf_cos_inline(r, wi);
}

vec3 pn_vpl_contribution_with(const pn_lights *lights, const pn_vpl *v, vec3 intensity, const pn_vpl_receiver *r,
                              float min_dist2, vec3 *wi, float *dist) {
    if (v->kind == PN_VPL_DIRECTIONAL || v->kind == PN_VPL_ORIENTED || v->light < 0)
        return pn_vpl_contribution_inline(lights, v, intensity, r, min_dist2, wi, dist);
    /* A VPL at a scene light: its spot falloff or goniometric factor. */
    vec3 d = v3_sub(v->p, r->p);
    float len2 = v3_length2(d);
    if (!(len2 > 0.0f)) return v3(0, 0, 0);
    float len = sqrtf(len2);
    vec3 w = v3_scale(d, 1.0f / len);
    float g = 1.0f / (len2 > min_dist2 ? len2 : min_dist2);
    const pn_light *l = &lights->lights[v->light];
    if (l->kind == PN_LIGHT_SPOT)
        g *= spot_falloff(l, -v3_dot(w, l->n));
    else if (l->kind == PN_LIGHT_GONIOMETRIC) {
        float peak = lights->gonios[l->env].peak; /* the VPL carries emit * peak (pn_vpl_trace) */
        g *= pn_gonio_factor(lights, l, v3_neg(w)) / peak;
    }
    *wi = w;
    *dist = len;
    if (g <= 0.0f) return v3(0, 0, 0);
    if (l->kind == PN_LIGHT_PROJECTION) {
        /* The pixel relative to the VPL's intensity, emit * peak (pn_vpl_trace). */
        float peak = lights->projections[l->env].peak;
        vec3 f = pn_projection_factor(lights, l, v3_neg(w));
        if (v3_is_zero(f) || !(peak > 0.0f)) return v3(0, 0, 0);
        if (r->wl.on)
            return v3_mul(pn_vpl_brdf_cos_inline(r, w),
                          pn_swl_illuminant(&r->wl, v3_mul(intensity, v3_scale(f, g / peak))));
        return v3_mul(v3_mul(pn_vpl_brdf_cos_inline(r, w), intensity), v3_scale(f, g / peak));
    }
    return pn_vpl_scaled_product(lights, v, pn_vpl_brdf_cos_inline(r, w), intensity, g, &r->wl);
}

vec3 pn_vpl_contribution(const pn_lights *lights, const pn_vpl *v, const pn_vpl_receiver *r, float min_dist2, vec3 *wi,
                         float *dist) {
    return pn_vpl_contribution_with(lights, v, v->intensity, r, min_dist2, wi, dist);
}

bool pn_vpl_shadow_ray(const pn_accel *accel, const pn_vpl_receiver *r, float dist, vec3 *o, float *tmax) {
    float eps = pn_accel_ray_epsilon(accel, r->p);
    *o = v3_madd(r->p, r->ng, eps);
    *tmax = isinf(dist) ? INFINITY : dist * (1.0f - 1e-3f) - eps;
    return *tmax > 0.0f;
}

float pn_vpl_transmittance(const pn_accel *accel, const pn_vpl_receiver *r, vec3 wi, float dist, bool thin_glass) {
    vec3 o;
    float tmax;
    if (!pn_vpl_shadow_ray(accel, r, dist, &o, &tmax)) return 1.0f;
    if (!thin_glass || !pn_accel_has_thin_glass(accel))
        return pn_accel_occluded(accel, o, wi, 0.0f, tmax) ? 0.0f : 1.0f;
    return pn_accel_transmittance(accel, o, wi, 0.0f, tmax);
}

bool pn_vpl_visible(const pn_accel *accel, const pn_vpl_receiver *r, vec3 wi, float dist) {
    vec3 o;
    float tmax;
    if (!pn_vpl_shadow_ray(accel, r, dist, &o, &tmax)) return true;
    return !pn_accel_occluded(accel, o, wi, 0.0f, tmax);
}
