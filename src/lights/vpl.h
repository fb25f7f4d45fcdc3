/* vpl.h — virtual point lights (instant radiosity, Keller 1997) as the IlluminationCut paper
 * (Bus et al. 2015, §3 eq. 1 and §4 "Scenes") and Lightcuts (Walter et al. 2005, §3) use them:
 * one set of point emitters that carries the direct light of every scene light and the
 * indirect light of light paths up to a depth, with the contribution of one VPL to one
 * receiving point (eq. 1: M · G · V · I) and its clamping.
 *
 * Three kinds, as Lightcuts keeps them in separate trees:
 *   OMNI        point, spot, goniometric and projection lights, as themselves (exact direct
 *               light; a projection light's VPL carries emit times its image's largest channel);
 *   ORIENTED    Lambertian emitters: points sampled on area lights (their direct light) and the
 *               vertices of light paths at diffuse / glossy hits (indirect light);
 *   DIRECTIONAL distant lights as themselves, and directions sampled from environment maps.
 *
 * Departures, and why:
 *   - A VPL left at a glossy hit is a Lambertian emitter of the hit's diffuse reflectance only
 *     (the issue: "VPLs are Lambertian emitters"); light paths continue by cosine sampling with
 *     the diffuse albedo as Russian-roulette probability, and through perfect mirrors and
 *     dielectrics without leaving a VPL. Glossy-to-anything transport along light paths is
 *     therefore not carried (as in the paper, whose VPLs are Lambertian too).
 *   - Environment maps are sampled by uniform directions (not by luminance), which is unbiased
 *     and keeps VPL generation independent of the map's importance table.
 *   - Clamping (§4): the squared distance in G is never below (clamp fraction · scene radius)^2.
 *
 * Determinism: light path i draws its random numbers from a PCG stream seeded by (seed, i), and
 * paths are traced in index order, so the VPL set depends only on the scene and settings. */
#ifndef PN_LIGHTS_VPL_H
#define PN_LIGHTS_VPL_H

#include "accel/accel.h"
#include "core/error.h"
#include "core/vecmath.h"
#include "lights/lights.h"
#include "shade/bounds.h"
#include "shade/bsdf.h"
#include "spectral/transport.h"

#include <math.h>
#include <stdint.h>

struct pn_scene_s;

/* pn_vpl_kind (omni, oriented, directional) is declared in shade/bounds.h, whose bounds depend on it. */

typedef struct pn_vpl {
    vec3 p;         /* OMNI / ORIENTED: position; DIRECTIONAL: unit direction towards the light */
    vec3 n;         /* ORIENTED: unit emitting normal; OMNI spot: axis; else 0 */
    vec3 intensity; /* OMNI: intensity W/sr; ORIENTED: intensity along the normal; DIRECTIONAL:
                       irradiance on a surface facing the light */
    int32_t kind;   /* pn_vpl_kind */
    int32_t light;  /* OMNI: the scene light (spot falloff, goniometric factor); ORIENTED at an area
                       light (direct light): that light (its spectrum in spectral mode); else -1 */
} pn_vpl;

typedef struct pn_vpl_settings {
    uint32_t count;       /* VPLs wanted (at least the exact point / distant lights are kept) */
    uint32_t max_depth;   /* bounces of a light path that may leave a VPL (10) */
    float clamp_fraction; /* minimum point-VPL distance as a fraction of the scene radius (0.05) */
    uint64_t seed;
} pn_vpl_settings;

/* What pn_vpl_trace_with adds (zero = off). */
typedef struct pn_vpl_trace_options {
    /* Direct light only (Lightcuts §3's conversion of the lights alone): the exact lights, and
     * for every area light and environment map a stratified set of points (directions) with its
     * emission, their number in proportion to the light's power; no path bounces (max_depth is
     * not used). */
    bool direct_only;
    /* Called with the fraction of VPLs traced (now and then, and once before the first); when it
     * returns false, tracing stops with PN_ERROR_CANCELLED. NULL: never. */
    bool (*progress)(void *user, double fraction);
    void *progress_user;
} pn_vpl_trace_options;

typedef struct pn_vpl_set {
    pn_vpl *vpls;
    uint32_t count;
    uint32_t count_by_kind[PN_VPL_KIND_COUNT];
    uint32_t paths;       /* light paths traced */
    float clamp_distance; /* clamp_fraction * scene radius */
    float min_dist2;      /* its square */
    double seconds;
} pn_vpl_set;

/* Traces the VPL set. On success the set owns its array; free with pn_vpl_set_free. A scene
 * without lights gives an empty set (not an error). */
pn_status pn_vpl_trace(const struct pn_scene_s *scene, const pn_lights *lights, const pn_accel *accel,
                       const pn_vpl_settings *settings, pn_vpl_set *out, pn_err *err);
/* pn_vpl_trace with options (NULL: none); returns PN_ERROR_CANCELLED (and an empty set) when
 * options->progress asks to stop. */
pn_status pn_vpl_trace_with(const struct pn_scene_s *scene, const pn_lights *lights, const pn_accel *accel,
                            const pn_vpl_settings *settings, const pn_vpl_trace_options *options, pn_vpl_set *out,
                            pn_err *err);
void pn_vpl_set_free(pn_vpl_set *set);

/* What a receiving point needs for eq. 1: position, normals, view direction and its BRDF
 * (Lambert + normalised Blinn-Phong). */
typedef struct pn_vpl_receiver {
    vec3 p, ng, ns, wo;
    vec3 kd, ks; /* linear sRGB: the bounds use these */
    float exponent;
    /* What eq. 1 multiplies: kd and ks at the eye sample's wavelengths wl in spectral mode
     * (spectral/transport.h), else kd and ks themselves. VPL intensities are upsampled at wl where
     * they are used (pn_vpl_intensity_at); wl.on is false in RGB mode. */
    vec3 kd_w, ks_w;
    pn_swl wl;
} pn_vpl_receiver;

/* A receiver of linear sRGB reflectances (RGB mode: kd_w = kd, ks_w = ks, no wavelengths). */
static inline pn_vpl_receiver pn_vpl_receiver_rgb(vec3 p, vec3 ng, vec3 ns, vec3 wo, vec3 kd, vec3 ks, float exponent) {
    pn_vpl_receiver r = {p, ng, ns, wo, kd, ks, exponent, kd, ks, {.on = false}};
    return r;
}

/* The unshadowed contribution M · G · I of VPL v at receiver r (eq. 1 without V), with the
 * clamped distance; *wi receives the unit direction towards the VPL and *dist its distance
 * (INFINITY for directional VPLs). Returns zero when the VPL cannot light r. */
vec3 pn_vpl_contribution(const pn_lights *lights, const pn_vpl *v, const pn_vpl_receiver *r, float min_dist2, vec3 *wi,
                         float *dist);

/* Like pn_vpl_contribution but with the intensity replaced by `intensity` (eq. 3: the
 * representative's M and G with its cluster's summed intensity). Intensities are linear sRGB;
 * in spectral mode (r->wl.on) they are upsampled at r's wavelengths, here and in
 * pn_vpl_contribution_inline, by pn_vpl_intensity_at. */
vec3 pn_vpl_contribution_with(const pn_lights *lights, const pn_vpl *v, vec3 intensity, const pn_vpl_receiver *r,
                              float min_dist2, vec3 *wi, float *dist);

/* The BRDF M of eq. 1 times cos theta at r towards unit wi (0 below the horizon). */
vec3 pn_vpl_receiver_brdf_cos(const pn_vpl_receiver *r, vec3 wi);

/* pn_vpl_receiver_brdf_cos and pn_vpl_contribution_with as inline functions, for the cut
 * integrators' inner loops; the library functions are these (vpl.c). Clamps are comparisons, not
 * fmaxf, which this build calls in libm; the results are the same (no NaN reaches them, and +0
 * and -0 give the same powf). */
static inline vec3 pn_vpl_brdf_cos_inline(const pn_vpl_receiver *r, vec3 wi) {
    float cos_i = v3_dot(r->ns, wi);
    if (cos_i <= 0.0f || v3_dot(r->ng, wi) <= 0.0f) return v3(0, 0, 0);
    vec3 f = v3_scale(r->kd_w, PN_INV_PI);
    if (!v3_is_zero(r->ks_w)) {
        /* eq. 1: beta is the angle between the reflected view direction and the light. */
        vec3 refl = pn_reflect(r->wo, r->ns);
        float cb = v3_dot(refl, wi);
        if (!(cb > 0.0f)) cb = 0.0f;
        float lobe = (r->exponent + 2.0f) * (0.5f * PN_INV_PI) * powf(cb, r->exponent);
        f = v3_madd(f, r->ks_w, lobe);
    }
    return v3_scale(f, cos_i);
}

/* A VPL's (or its cluster's) RGB intensity at the wavelengths wl (RGB mode: itself), with the
 * spectrum of the VPL v (the representative of the cluster) scaled to the intensity's luminance:
 * the black body or tabulated spectrum of v's scene light when it has one, else v's RGB intensity
 * as an illuminant. For
 * v's own intensity this is v's spectrum; for a cluster of one colour it is the cluster's; for a
 * cluster of mixed colours the representative's colour stands for the cluster's, as its geometry
 * does (eq. 3; the representative is drawn in proportion to luminance, so the colour is right on
 * average). One spectrum per light colour also keeps pn_swl_illuminant_on's table hit. */
static inline vec3 pn_vpl_intensity_at(const pn_lights *lights, const pn_vpl *v, vec3 intensity, const pn_swl *wl) {
    if (!wl->on) return intensity;
    float yv = v3_luminance(v->intensity), yi = v3_luminance(intensity);
    vec3 colour = yv > 0.0f ? v->intensity : intensity;
    float k = yv > 0.0f ? yi / yv : 1.0f;
    vec3 s;
    if (v->light >= 0 && v->kind != PN_VPL_DIRECTIONAL &&
        (lights->lights[v->light].kelvin > 0.0f || lights->lights[v->light].spd))
        s = pn_light_radiance_spectral(lights, &lights->lights[v->light], colour, wl);
    else
        s = pn_swl_illuminant_on(wl, colour);
    return k == 1.0f ? s : v3_scale(s, k);
}

/* (f * intensity) * g with the intensity at the wavelengths wl; in spectral mode the upsampling
 * is skipped when f is zero (a VPL below the receiver's horizon). */
static inline vec3 pn_vpl_scaled_product(const pn_lights *lights, const pn_vpl *v, vec3 f, vec3 intensity, float g,
                                         const pn_swl *wl) {
    if (!wl->on) return v3_scale(v3_mul(f, intensity), g);
    if (v3_is_zero(f)) return f;
    return v3_scale(v3_mul(f, pn_vpl_intensity_at(lights, v, intensity, wl)), g);
}

/* VPLs at scene lights (spot falloff, goniometric factor) go through the library function. */
static inline vec3 pn_vpl_contribution_inline(const pn_lights *lights, const pn_vpl *v, vec3 intensity,
                                              const pn_vpl_receiver *r, float min_dist2, vec3 *wi, float *dist) {
    vec3 w;
    float g, len;
    if (v->kind == PN_VPL_DIRECTIONAL) {
        w = v->p;
        g = 1.0f;
        len = INFINITY;
    } else {
        if (v->kind != PN_VPL_ORIENTED && v->light >= 0)
            return pn_vpl_contribution_with(lights, v, intensity, r, min_dist2, wi, dist);
        vec3 d = v3_sub(v->p, r->p);
        float len2 = v3_length2(d);
        if (!(len2 > 0.0f)) return v3(0, 0, 0);
        len = sqrtf(len2);
        w = v3_scale(d, 1.0f / len);
        g = 1.0f / (len2 > min_dist2 ? len2 : min_dist2);
        if (v->kind == PN_VPL_ORIENTED) {
            float c = -v3_dot(v->n, w);
            if (c <= 0.0f) return v3(0, 0, 0);
            g *= c;
        }
    }
    *wi = w;
    *dist = len;
    if (g <= 0.0f) return v3(0, 0, 0);
    return pn_vpl_scaled_product(lights, v, pn_vpl_brdf_cos_inline(r, w), intensity, g, &r->wl);
}

/* True when nothing blocks the segment from r towards the VPL (a shadow ray). */
/* The shadow ray's transmittance in [0, 1] (render/render_job.h's pn_shadow_transmittance for a
 * VPL receiver): thin glass panes pass it attenuated when thin_glass is true, else block it. */
float pn_vpl_transmittance(const pn_accel *accel, const pn_vpl_receiver *r, vec3 wi, float dist, bool thin_glass);
bool pn_vpl_visible(const pn_accel *accel, const pn_vpl_receiver *r, vec3 wi, float dist);

/* The shadow ray pn_vpl_visible traces (origin *o, direction wi, t in (0, *tmax)), for callers
 * that trace several together; false when the segment is empty (the VPL then counts as visible
 * without a ray). */
bool pn_vpl_shadow_ray(const pn_accel *accel, const pn_vpl_receiver *r, float dist, vec3 *o, float *tmax);

#endif
