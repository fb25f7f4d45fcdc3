/* bsdf.c — material evaluation: mix materials resolved per hit, textures looked up, normals
 * oriented, Lambert + Blinn–Phong. */
#include "shade/bsdf.h"

#include "core/sampling.h"
#include "spectral/metals.h"
#include "spectral/transport.h"

#include <string.h>

/* SplitMix64's finaliser (Steele, Lea and Flood 2014): a 64-bit mixing function. */
static uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static uint64_t hash_float(uint64_t h, float f) {
    uint32_t bits;
    if (f == 0.0f) f = 0.0f; /* -0 and +0 hash alike */
    memcpy(&bits, &f, sizeof bits);
    return mix64(h ^ (uint64_t)bits);
}

float pn_mix_hash(vec3 p, vec3 wo, int a, int b) {
    uint64_t h = 0x9e3779b97f4a7c15ull;
    h = hash_float(h, p.x);
    h = hash_float(h, p.y);
    h = hash_float(h, p.z);
    h = hash_float(h, wo.x);
    h = hash_float(h, wo.y);
    h = hash_float(h, wo.z);
    h = mix64(h ^ ((uint64_t)(uint32_t)a << 32 | (uint32_t)b));
    return (float)(h >> 40) * (1.0f / 16777216.0f); /* 24 bits: [0, 1) exactly in float */
}

int pn_material_resolve(const struct pn_scene_s *scene, int material, vec3 p, vec3 wo, float u, float v) {
    /* Mixes refer to materials defined before them, so the chain ends; the bound guards it. */
    for (int depth = 0; depth < 64; depth++) {
        if (material < 0 || material >= scene->material_count) return material;
        const pn_material *m = &scene->materials[material];
        if (m->kind != PN_MATERIAL_MIX) return material;
        vec3 c = pn_texture_eval(scene, m->mix_amount, u, v);
        float amount = (c.x + c.y + c.z) * (1.0f / 3.0f);
        /* pbrt-v4 MixMaterial::ChooseMaterial: amount <= 0 the first, >= 1 the second, else the
         * second when amount >= a hash of the hit in [0, 1). */
        if (amount <= 0.0f)
            material = m->mix[0];
        else if (amount >= 1.0f)
            material = m->mix[1];
        else
            material = amount < pn_mix_hash(p, wo, m->mix[0], m->mix[1]) ? m->mix[0] : m->mix[1];
    }
    return -1;
}

void pn_bsdf_at(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, pn_bsdf *out) {
    pn_bsdf_at_spectral(scene, hit, wo, NULL, out);
}

/* The material's RGB values (kd, ks, specular) looked up at the hit; *base_kd the diffuse
 * texture's value before a coating, *coat the material when it is coated (else NULL). */
static void bsdf_at_rgb(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, pn_bsdf *out, vec3 *base_kd,
                        const pn_material **coat, const pn_material **mat) {
    *coat = NULL;
    int mi = pn_material_resolve(scene, hit->material, hit->p, wo, hit->u, hit->v);
    const pn_material *m = (mi >= 0 && mi < scene->material_count) ? &scene->materials[mi] : NULL;
    *mat = m;
    out->ng = hit->ng;
    out->ns = hit->ns;
    out->entering = v3_dot(hit->ng, wo) >= 0.0f;
    if (!out->entering) {
        out->ng = v3_neg(out->ng);
        out->ns = v3_neg(out->ns);
    }
    if (!m) {
        out->kind = PN_MATERIAL_LAMBERT_BLINN;
        out->kd = v3(0.5f, 0.5f, 0.5f);
        out->ks = v3(0, 0, 0);
        out->exponent = 1.0f;
        out->specular = v3(0, 0, 0);
        out->eta = 1.0f;
        return;
    }
    out->kind = m->kind;
    out->kd = pn_texture_eval_footprint(scene, m->kd, hit->u, hit->v, hit->duv);
    *base_kd = out->kd;
    if (m->coated) {
        *coat = m;
        out->kd = pn_coated_diffuse(out->kd, m->coat_transmission, m->coat_internal);
    }
    out->ks = pn_texture_eval_footprint(scene, m->ks, hit->u, hit->v, hit->duv);
    out->exponent = m->exponent;
    out->specular = m->specular;
    out->eta = m->eta > 0.0f ? m->eta : 1.5f;
}

/* A tabulated reflectance at the wavelengths. */
static vec3 spd_at(const pn_spd *s, const struct pn_swl *wl) {
    float f[PN_SWL_COUNT];
    for (int i = 0; i < PN_SWL_COUNT; i++) f[i] = (float)pn_spd_eval(s, wl->lambda[i]);
    return v3(f[0], f[1], f[2]);
}

void pn_bsdf_at_spectral(const struct pn_scene_s *scene, const pn_hit *hit, vec3 wo, const struct pn_swl *wl,
                         pn_bsdf *out) {
    vec3 base_kd = v3(0, 0, 0);
    const pn_material *coat, *m;
    bsdf_at_rgb(scene, hit, wo, out, &base_kd, &coat, &m);
    out->rgb_kd = out->kd;
    out->rgb_ks = out->ks;
    out->rgb_specular = out->specular;
    out->metal = m && (m->eta_table || m->eta_spd) && (m->k_table || m->k_spd) ? m : NULL;
    out->kd_spd = m && !coat ? m->kd_spd : NULL;
    out->wl = pn_swl_active(wl) ? wl : NULL;
    if (!out->wl) return;
    /* The coating's series is per wavelength, so the base's reflectance is upsampled before it:
     * the texture's RGB is what pbrt-v4 upsamples too. */
    const vec3 base = m && m->kd_spd ? spd_at(m->kd_spd, wl) : pn_swl_albedo(wl, coat ? base_kd : out->kd);
    out->kd = coat ? pn_coated_diffuse(base, coat->coat_transmission, coat->coat_internal) : base;
    if (out->metal) {
        /* A conductor with tabulated eta and k: its F0 at each wavelength (metals.h), where RGB
         * mode has F0 at 630, 532 and 465 nm in ks (a Blinn lobe) or specular (a mirror). */
        const vec3 f0 = pn_bsdf_metal_f0(out, wl);
        if (m->kind == PN_MATERIAL_MIRROR) {
            out->ks = pn_swl_albedo(wl, out->ks);
            out->specular = f0;
        } else {
            out->ks = f0;
            out->specular = pn_swl_albedo(wl, out->specular);
        }
        return;
    }
    out->ks = pn_swl_albedo(wl, out->ks);
    out->specular = pn_swl_albedo(wl, out->specular);
}

/* eta or k of a conductor at lambda: its named table, else its tabulated spectrum. */
static double metal_constant(const pn_metal_table *table, const pn_spd *spd, double lambda) {
    return table ? pn_metal_eval(table, lambda) : pn_spd_eval(spd, lambda);
}

vec3 pn_bsdf_kd_at(const pn_bsdf *b, const struct pn_swl *wl) {
    return b->kd_spd ? spd_at(b->kd_spd, wl) : pn_swl_albedo(wl, b->rgb_kd);
}

vec3 pn_bsdf_metal_f0(const pn_bsdf *b, const struct pn_swl *wl) {
    const pn_material *m = b->metal;
    float f[PN_SWL_COUNT];
    for (int i = 0; i < PN_SWL_COUNT; i++)
        f[i] = (float)pn_conductor_f0(metal_constant(m->eta_table, m->eta_spd, wl->lambda[i]),
                                      metal_constant(m->k_table, m->k_spd, wl->lambda[i]));
    return v3(f[0], f[1], f[2]);
}

vec3 pn_bsdf_eval(const pn_bsdf *b, vec3 wo, vec3 wi) {
    float cos_i = v3_dot(b->ns, wi);
    if (cos_i <= 0.0f || v3_dot(b->ng, wi) <= 0.0f) return v3(0, 0, 0);
    vec3 f = v3_scale(b->kd, PN_INV_PI);
    if (!v3_is_zero(b->ks)) {
        vec3 h = v3_add(wo, wi);
        float hl = v3_length(h);
        if (hl > 0.0f) {
            float cos_h = fmaxf(0.0f, v3_dot(b->ns, v3_scale(h, 1.0f / hl)));
            float lobe = (b->exponent + 2.0f) * (0.5f * PN_INV_PI) * powf(cos_h, b->exponent);
            f = v3_madd(f, b->ks, lobe);
        }
    }
    return f;
}

float pn_bsdf_diffuse_share(const pn_bsdf *b) {
    const float wd = fmaxf(0.0f, v3_luminance(b->kd)), ws = fmaxf(0.0f, v3_luminance(b->ks));
    return wd + ws > 0.0f ? wd / (wd + ws) : 0.0f;
}

/* The glossy lobe's density of wi: the half vector's (n + 1) / (2 pi) cos^n over 4 wo.h. */
static float blinn_pdf(const pn_bsdf *b, vec3 wo, vec3 wi) {
    vec3 h = v3_add(wo, wi);
    float hl = v3_length(h);
    if (!(hl > 0.0f)) return 0.0f;
    h = v3_scale(h, 1.0f / hl);
    float cos_h = v3_dot(b->ns, h), wo_h = v3_dot(wo, h);
    if (cos_h <= 0.0f || wo_h <= 0.0f) return 0.0f;
    return (b->exponent + 1.0f) * (0.5f * PN_INV_PI) * powf(cos_h, b->exponent) / (4.0f * wo_h);
}

/* A direction from the glossy lobe: h with density (n + 1) / (2 pi) cos^n(theta_h) about ns
 * (cos(theta_h) = u^(1 / (n + 1))), wo reflected about it. */
static bool blinn_direction(const pn_bsdf *b, vec3 wo, float u2, float u3, vec3 *d) {
    vec3 t, bt;
    v3_basis(b->ns, &t, &bt);
    float cos_h = powf(u2, 1.0f / (b->exponent + 1.0f));
    float sin_h = sqrtf(fmaxf(0.0f, 1.0f - cos_h * cos_h));
    float phi = 2.0f * PN_PI * u3;
    vec3 h = v3_add(v3_add(v3_scale(t, sin_h * cosf(phi)), v3_scale(bt, sin_h * sinf(phi))), v3_scale(b->ns, cos_h));
    float wo_h = v3_dot(wo, h);
    if (wo_h <= 0.0f) return false;
    *d = v3_sub(v3_scale(h, 2.0f * wo_h), wo);
    return true;
}

/* A sampled direction d (not unit length) normalised, with its density under pdf_of; false where
 * that density is not positive and finite (below the surface, or outside the lobe). */
static bool accept_direction(const pn_bsdf *b, vec3 wo, vec3 d, float (*pdf_of)(const pn_bsdf *, vec3, vec3), vec3 *wi,
                             float *pdf) {
    float len = v3_length(d);
    if (!(len > 0.0f)) return false;
    d = v3_scale(d, 1.0f / len);
    float p = pdf_of(b, wo, d);
    if (!(p > 0.0f) || !isfinite(p)) return false;
    *wi = d;
    *pdf = p;
    return true;
}

float pn_bsdf_pdf_glossy(const pn_bsdf *b, vec3 wo, vec3 wi) {
    if (v3_is_zero(b->ks) || v3_dot(b->ns, wi) <= 0.0f || v3_dot(b->ng, wi) <= 0.0f) return 0.0f;
    return blinn_pdf(b, wo, wi);
}

bool pn_bsdf_sample_glossy(const pn_bsdf *b, vec3 wo, float u1, float u2, vec3 *wi, float *pdf) {
    vec3 d;
    if (v3_is_zero(b->ks) || !blinn_direction(b, wo, u1, u2, &d)) return false;
    return accept_direction(b, wo, d, pn_bsdf_pdf_glossy, wi, pdf);
}

float pn_bsdf_pdf(const pn_bsdf *b, vec3 wo, vec3 wi) {
    float cos_i = v3_dot(b->ns, wi);
    if (cos_i <= 0.0f || v3_dot(b->ng, wi) <= 0.0f) return 0.0f;
    const float pd = pn_bsdf_diffuse_share(b);
    float p = pd * cos_i * PN_INV_PI;
    if (pd < 1.0f) p += (1.0f - pd) * blinn_pdf(b, wo, wi);
    return p;
}

bool pn_bsdf_sample(const pn_bsdf *b, vec3 wo, float u1, float u2, float u3, vec3 *wi, float *pdf) {
    const float wd = fmaxf(0.0f, v3_luminance(b->kd)), ws = fmaxf(0.0f, v3_luminance(b->ks));
    if (!(wd + ws > 0.0f)) return false;
    vec3 d;
    if (u1 * (wd + ws) < wd) {
        vec3 t, bt;
        v3_basis(b->ns, &t, &bt);
        vec3 l = pn_sample_cosine_hemisphere(u2, u3);
        d = v3_add(v3_add(v3_scale(t, l.x), v3_scale(bt, l.y)), v3_scale(b->ns, l.z));
    } else if (!blinn_direction(b, wo, u2, u3, &d)) {
        return false;
    }
    return accept_direction(b, wo, d, pn_bsdf_pdf, wi, pdf);
}

vec3 pn_coated_diffuse(vec3 kd, float transmission, float internal) {
    return v3(kd.x * transmission / (1.0f - kd.x * internal), kd.y * transmission / (1.0f - kd.y * internal),
              kd.z * transmission / (1.0f - kd.z * internal));
}

bool pn_refract(vec3 wo, vec3 n, float eta, vec3 *wt) {
    float cos_i = v3_dot(n, wo);
    float sin2_i = fmaxf(0.0f, 1.0f - cos_i * cos_i);
    float sin2_t = sin2_i / (eta * eta);
    if (sin2_t >= 1.0f) return false;
    float cos_t = sqrtf(1.0f - sin2_t);
    *wt = v3_add(v3_scale(v3_neg(wo), 1.0f / eta), v3_scale(n, cos_i / eta - cos_t));
    return true;
}
