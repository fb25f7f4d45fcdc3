/* bsdf.h — penumbra's reflection models at a surface point: Lambert + normalised Blinn–Phong
 * (IlluminationCut eq. 1), perfect mirror, and smooth dielectric for eye rays. */
#ifndef PN_SHADE_BSDF_H
#define PN_SHADE_BSDF_H

#include "accel/accel.h"
#include "core/optics.h"
#include "core/vecmath.h"
#include "scene/scene.h"

typedef struct pn_bsdf {
    pn_material_kind kind;
    vec3 kd;        /* diffuse reflectance */
    vec3 ks;        /* glossy coefficient */
    float exponent; /* Blinn–Phong n */
    vec3 specular;  /* mirror / dielectric tint */
    float eta;
    vec3 ng, ns;   /* normals flipped to the side of wo */
    bool entering; /* wo is on the side the geometric normal points to (dielectric: outside) */
    /* Spectral mode (spectral/transport.h): kd, ks and specular above hold their values at the
     * wavelengths *wl, and these their linear sRGB (for AOVs and bounds); in RGB mode wl is NULL
     * and these equal kd, ks, specular. */
    const struct pn_swl *wl;
    vec3 rgb_kd, rgb_ks, rgb_specular;
    /* A conductor whose eta and k are spectra (pn_material's eta/k tables or spds), else NULL:
     * spectral mode evaluates its F0 at each wavelength (pn_bsdf_metal_f0). */
    const pn_material *metal;
    /* An uncoated material's tabulated reflectance spectrum (pn_material.kd_spd), else NULL. */
    const struct pn_spd *kd_spd;
} pn_bsdf;

/* Evaluates the material at a hit, seen from direction wo (unit, pointing away from the
 * surface towards the viewer). */
void pn_bsdf_at(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, pn_bsdf *out);
/* pn_bsdf_at at the wavelengths wl (NULL: RGB): reflectances upsampled as albedo spectra where
 * they are looked up (pbrt-v4's RGBAlbedoSpectrum of the texture's value). wl must outlive out. */
struct pn_swl;
void pn_bsdf_at_spectral(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, const struct pn_swl *wl,
                         pn_bsdf *out);

/* The material seen at a hit: `material` itself, or for a MIX material (pbrt-v4's mix) the
 * input chosen at point p seen from wo with the mix's amount at (u, v), repeated through nested
 * mixes. Deterministic: a hash of p, wo and the two inputs, as pbrt-v4's ChooseMaterial. */
int pn_material_resolve(const struct pn_scene_s *scene, int material, vec3 p, vec3 wo, float u, float v);

/* The hash in [0, 1) behind pn_material_resolve's choice between materials a and b. */
float pn_mix_hash(vec3 p, vec3 wo, int a, int b);

/* f(wo, wi) for the non-specular part (Lambert + Blinn); zero below either normal's horizon. */
vec3 pn_bsdf_eval(const pn_bsdf *bsdf, vec3 wo, vec3 wi);

/* BSDF sampling of the non-specular part (Lambert + normalised Blinn-Phong), for MIS with light
 * sampling. A lobe is chosen by its weight (the luminance of kd for the diffuse lobe, of ks for the
 * glossy one: their albedos at normal incidence, up to the Blinn lobe's loss below the horizon);
 * the diffuse lobe samples cos(theta_i) / pi about ns, the glossy one the half vector h with
 * density (n + 1) / (2 pi) cos^n(theta_h) about ns, wi = wo reflected about h, whose density is
 * that over 4 wo.h. u1 picks the lobe, (u2, u3) the direction. *pdf is the mixture's solid-angle
 * density at wi (pn_bsdf_pdf). False when the sample carries nothing (no lobe, h facing away from
 * wo, or wi below either normal's horizon). */
bool pn_bsdf_sample(const pn_bsdf *bsdf, vec3 wo, float u1, float u2, float u3, vec3 *wi, float *pdf);
/* The solid-angle density with which pn_bsdf_sample draws wi (0 where f is 0 by the horizons). */
float pn_bsdf_pdf(const pn_bsdf *bsdf, vec3 wo, vec3 wi);
/* The glossy lobe alone (wo, u1, u2 as the glossy branch of pn_bsdf_sample): a strategy for MIS
 * with light sampling where light sampling misses narrow highlights; *pdf its own density
 * (pn_bsdf_pdf_glossy). False without a glossy lobe or when the sample carries nothing. */
bool pn_bsdf_sample_glossy(const pn_bsdf *bsdf, vec3 wo, float u1, float u2, vec3 *wi, float *pdf);
float pn_bsdf_pdf_glossy(const pn_bsdf *bsdf, vec3 wo, vec3 wi);
/* The probability pn_bsdf_sample gives the diffuse lobe (1 - that the glossy one). */
float pn_bsdf_diffuse_share(const pn_bsdf *bsdf);

/* The diffuse reflectance at the wavelengths wl of a bsdf evaluated in RGB (its rgb_kd upsampled
 * as an albedo, or its tabulated spectrum): for light samples that draw their own wavelengths. */
vec3 pn_bsdf_kd_at(const pn_bsdf *bsdf, const struct pn_swl *wl);

/* The normal-incidence reflectance of bsdf->metal (not NULL) at the wavelengths wl, from its
 * tabulated eta and k (spectral/metals.h's pn_conductor_f0). */
vec3 pn_bsdf_metal_f0(const pn_bsdf *bsdf, const struct pn_swl *wl);

/* True when the BSDF has a non-specular lobe (so light sampling applies). */
static inline bool pn_bsdf_is_shadable(const pn_bsdf *b) {
    return b->kind == PN_MATERIAL_LAMBERT_BLINN && (!v3_is_zero(b->kd) || !v3_is_zero(b->ks));
}

/* The diffuse reflectance, seen from outside, of a Lambertian base of reflectance kd (each
 * channel in [0, 1]) under a smooth dielectric coating (scene.h, pn_material.coated): the light
 * that the coating reflects back down is reflected again by the base, a geometric series. */
vec3 pn_coated_diffuse(vec3 kd, float transmission, float internal);

/* Perfect reflection of wo about n. */
static inline vec3 pn_reflect(vec3 wo, vec3 n) {
    return v3_sub(v3_scale(n, 2.0f * v3_dot(wo, n)), wo);
}

/* Refraction of wo through n (n on wo's side) with eta = eta_t / eta_i; false on total internal
 * reflection. */
bool pn_refract(vec3 wo, vec3 n, float eta, vec3 *wt);

#endif
