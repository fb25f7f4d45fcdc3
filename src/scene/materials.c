/* materials.c — mapping pbrt-v4 materials onto penumbra's reflection models.
 *
 * penumbra has four models (scene.h): LAMBERT_BLINN (kd/pi + ks (n+2)/(2 pi) cos^n), MIRROR,
 * DIELECTRIC (smooth, eye rays only) and INTERFACE. Every pbrt-v4 material type is mapped here,
 * and the material's description says what was done:
 *
 *   pbrt type            penumbra
 *   -------------------  ------------------------------------------------------------------
 *   diffuse              LAMBERT kd = reflectance (default 0.5), ks = 0
 *   coateddiffuse        LAMBERT kd = reflectance (0.5) seen through the coating: kd x T /
 *                        (1 - kd x R), T = (1 - Fbar)^2 / eta^2, R = 1 - (1 - Fbar) / eta^2,
 *                        Fbar the coating's hemispherical Fresnel reflectance (scene.h); for
 *                        eta 1.5 and kd 0.5 the base looks about half as bright (0.261). Plus BLINN
 *                        ks = F0 of the coating, ((eta - 1) / (eta + 1))^2 (eta default 1.5 ->
 *                        0.04), n from roughness
 *   conductor            smooth (alpha < 1e-3): MIRROR, specular = F0 of the metal;
 *                        rough: BLINN ks = F0, kd = 0, n from roughness. F0 per channel is
 *                        ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2) from eta, k (default
 *                        metal-Cu), or "reflectance" when given
 *   coatedconductor      BLINN ks = F0 of the conductor (conductor.eta / conductor.k or
 *                        reflectance), kd = 0, n from alpha = sqrt(alpha_i^2 + alpha_c^2) of the
 *                        interface and conductor roughnesses (the metal's lobe blurred by the
 *                        coating; pbrt-v4 honours both "interface.roughness" and
 *                        "conductor.roughness")
 *   dielectric,          DIELECTRIC with eta (a float, or a spectrum's value at 550 nm; default
 *   thindielectric       1.5), white; a rough dielectric is rendered smooth, with a warning
 *   diffusetransmission  LAMBERT kd = reflectance (default 0.25) * scale (a textured reflectance
 *                        gets a scale texture "TEX x scale"); transmission dropped with a warning
 *   mix                  MIX: per hit, the second of "materials" with probability "amount"
 *                        (a float or float texture, default 0.5), else the first, chosen by a
 *                        hash of the hit point and direction as pbrt-v4's MixMaterial does
 *                        (shade/bsdf.c); a constant amount <= 0 or >= 1 is one of the two; a
 *                        mix with an "interface" input takes the input of larger weight, with
 *                        a warning
 *   measured, hair,      LAMBERT substitutes with a warning: kd = 0.5 (measured), the hair
 *   subsurface           "reflectance" (pbrt-v4's name; pbrt-v3's "color" is read too) or 0.3
 *                        (hair), "reflectance" or 0.5 (subsurface)
 *   interface            INTERFACE
 *
 * Older scenes written for pbrt-v3 use its material names, which are mapped with the same models
 * (descriptions read "pbrt-v3 TYPE"). Their inputs have pbrt-v3's names and defaults, and their
 * roughness goes through pbrt-v3's remapping (below):
 *
 *   pbrt-v3 type         penumbra
 *   -------------------  ------------------------------------------------------------------
 *   matte                LAMBERT kd = Kd (default 0.5); an Oren-Nayar "sigma" > 0 is ignored
 *                        (noted in the description)
 *   plastic              LAMBERT kd = Kd (0.25) + BLINN ks = Ks (0.25), n from "roughness" (0.1)
 *   substrate            LAMBERT kd = Kd (0.5) + BLINN ks = Ks (0.5, taken as the reflectance at
 *                        normal incidence), n from "uroughness" / "vroughness" (0.1 each)
 *   uber                 LAMBERT kd = Kd (0.25) + BLINN ks = Ks (0.25), n from "roughness" (0.1)
 *                        or u/v (a missing vroughness follows uroughness); the specular
 *                        reflection Kr and transmission Kt (default 0) are dropped with a
 *                        warning when non-zero, as is an "opacity" below 1; "eta" / "index"
 *                        is read and reported only
 *   glass                DIELECTRIC with "eta" or, failing that, "index" (1.5). Kr (1) tints
 *                        it when not white (said in the description); Kr = 0 takes the tint
 *                        from Kt instead (penumbra's glass always reflects); any other
 *                        non-white Kt is dropped with a warning; a rough glass (u/v roughness
 *                        not 0) is rendered smooth with a warning
 *   metal                as conductor: eta / k (default copper), "roughness" (0.01) or u/v;
 *                        MIRROR when alpha < 1e-3, else BLINN ks = F0, kd = 0
 *   mirror               MIRROR, specular = Kr (0.9)
 *   mix                  with "namedmaterial1" / "namedmaterial2" instead of "materials": as
 *                        mix, but "amount" (channel average) is the probability of the first
 *                        material (pbrt-v3's blend weights it by amount)
 *   translucent,         LAMBERT substitutes with a warning: kd = "Kd", "color" or
 *   kdsubsurface,        "reflectance" (the first one given), else 0.5
 *   fourier, disney
 *
 * pbrt-v3's remaproughness (default true) is not pbrt-v4's square root: its TrowbridgeReitz
 * RoughnessToAlpha is a quartic polynomial in x = ln(max(roughness, 1e-3)),
 *   alpha = 1.62142 + 0.819955 x + 0.1734 x^2 + 0.0171201 x^3 + 0.000640711 x^4,
 * so roughness 0.1 gives alpha 0.4618 (n = 7.38), 0.5 gives 1.131 (n clamped to 1), and even
 * roughness 0 gives alpha 0.047 (a remapped pbrt-v3 surface is never a perfect mirror).
 *
 * Roughness: "uroughness" / "vroughness" (each falling back to "roughness", default 0) are
 * averaged; with "remaproughness" (default true) alpha = sqrt(roughness) as pbrt-v4's
 * TrowbridgeReitz RoughnessToAlpha does, else alpha = roughness. The Blinn–Phong exponent with
 * the same highlight width as a microfacet lobe of width alpha is n = 2 / alpha^2 - 2, clamped
 * to [1, 10000]; alpha = 0 (perfectly smooth) gives n = 10000. A roughness given as a texture
 * uses the texture's value when it is constant, else 0.5 with a warning (the exponent is one
 * number per material).
 *
 * Bump and normal maps ("displacement", "normalmap"; pbrt-v3's "bumpmap") are ignored with a
 * warning. Parameters of the layered models that have no counterpart here (thickness, albedo, g,
 * maxdepth, nsamples) are accepted silently.
 */
#include "scene/build.h"

#include "core/optics.h"
#include "spectral/cie.h"
#include "spectral/metals.h"

#include "scene/parser_internal.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PN_BLINN_MAX_EXPONENT 10000.0
#define PN_SMOOTH_ALPHA 1e-3

/* What is being built: the material, its label for messages and the description pieces. */
typedef struct builder {
    struct pn_scene_s *scene;
    const pn_params *ps;
    const char *label; /* the name, or "Material" for anonymous ones */
    pn_material m;
    char model[384];  /* "Lambert kd=0.5 + Blinn ks=0.04 n=98" */
    char note[512];   /* "(roughness 0.1)" */
    bool v3;          /* a pbrt-v3 material name: "pbrt-v3" in the description, v3 bump map */
    const char *type; /* the pbrt material type, as written */
} builder;

/* ---- small helpers ------------------------------------------------------------------------ */

static void fmt_rgb(char *buf, size_t size, vec3 c) {
    if (c.x == c.y && c.y == c.z)
        snprintf(buf, size, "%.4g", (double)c.x);
    else
        snprintf(buf, size, "(%.4g, %.4g, %.4g)", (double)c.x, (double)c.y, (double)c.z);
}

static void fmt_ref(const struct pn_scene_s *scene, char *buf, size_t size, pn_texref r) {
    if (r.texture >= 0 && r.texture < scene->texture_count)
        snprintf(buf, size, "texture '%s'", scene->textures[r.texture].name ? scene->textures[r.texture].name : "?");
    else
        fmt_rgb(buf, size, r.value);
}

static pn_texref constant_ref(vec3 v) {
    pn_texref r;
    r.texture = -1;
    r.value = v;
    return r;
}

/* The value of a texref when it must be one number: constants, constant textures and scale
 * chains of constants are exact; anything else gives `fallback` and *varies = true. */
static vec3 texref_constant(const struct pn_scene_s *scene, pn_texref r, vec3 fallback, bool *varies) {
    if (r.texture < 0 || r.texture >= scene->texture_count) return r.value;
    const pn_texture *t = &scene->textures[r.texture];
    if (t->kind == PN_TEXTURE_CONSTANT) return t->value;
    if (t->kind == PN_TEXTURE_SCALE) {
        bool va = false, vb = false;
        vec3 a = texref_constant(scene, t->a, fallback, &va);
        vec3 b = texref_constant(scene, t->b, fallback, &vb);
        if (!va && !vb) return v3_mul(a, b);
    }
    *varies = true;
    return fallback;
}

static const pn_param *find_param(const pn_params *ps, const char *name) {
    return pn_params_find(ps, name);
}

/* Reads and ignores parameters that have no counterpart in penumbra's models. */
static void accept_silently(const pn_params *ps, const char *const *names, size_t n) {
    for (size_t i = 0; i < n; i++) (void)find_param(ps, names[i]);
}

static void consume_all(const pn_params *ps) {
    for (int i = 0; i < ps->count; i++) (void)find_param(ps, ps->items[i].name);
}

/* Appends a parenthesised remark to the description's note. */
static void add_note(builder *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void add_note(builder *b, const char *fmt, ...) {
    size_t len = strlen(b->note);
    if (len > 0 && len + 1 < sizeof b->note) {
        b->note[len++] = ' ';
        b->note[len] = '\0';
    }
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(b->note + len, sizeof b->note - len, fmt, ap);
    va_end(ap);
}

/* Warns about bump / normal maps, which penumbra does not apply (pbrt-v3 calls its bump map
 * "bumpmap"; pbrt-v4 has "displacement" and "normalmap"). */
static void warn_bump(builder *b) {
    const char *v4_names[] = {"displacement", "normalmap"};
    const char *v3_names[] = {"bumpmap"};
    const char *const *names = b->v3 ? v3_names : v4_names;
    int count = b->v3 ? 1 : 2;
    for (int i = 0; i < count; i++) {
        const pn_param *p = find_param(b->ps, names[i]);
        if (p) pn_warn_at(b->scene, p->loc, "%s: \"%s\" (bump mapping) is ignored", b->label, names[i]);
    }
}

/* One float input that may be a texture, reduced to a number. */
static pn_status float_input(builder *b, const char *name, double def, double *out, bool *found, pn_err *err) {
    const pn_param *p = find_param(b->ps, name);
    if (found) *found = p != NULL;
    *out = def;
    if (!p) return PN_OK;
    pn_texref r;
    pn_status st = pn_params_texref(b->scene, b->ps, name, true, v3((float)def, (float)def, (float)def), &r, err);
    if (st != PN_OK) return st;
    bool varies = false;
    vec3 v = texref_constant(b->scene, r, v3(0.5f, 0.5f, 0.5f), &varies);
    if (varies)
        pn_warn_at(b->scene, p->loc, "%s: \"%s\" is a varying texture; the constant 0.5 is used instead", b->label,
                   name);
    *out = v.x;
    return PN_OK;
}

/* Roughness with pbrt-v4's parameter names under `prefix` ("" or "interface." / "conductor."),
 * as the average roughness and the microfacet alpha. */
static pn_status read_roughness(builder *b, const char *prefix, double *roughness, double *alpha, pn_err *err) {
    char un[64], vn[64], rn[64];
    snprintf(un, sizeof un, "%suroughness", prefix);
    snprintf(vn, sizeof vn, "%svroughness", prefix);
    snprintf(rn, sizeof rn, "%sroughness", prefix);
    double r = 0.0, u = 0.0, v = 0.0;
    bool has_u = false, has_v = false;
    pn_status st = float_input(b, rn, 0.0, &r, NULL, err);
    if (st == PN_OK) st = float_input(b, un, r, &u, &has_u, err);
    if (st == PN_OK) st = float_input(b, vn, r, &v, &has_v, err);
    if (st != PN_OK) return st;
    if (!has_u) u = r;
    if (!has_v) v = r;
    bool remap = true;
    st = pn_params_bool(b->ps, "remaproughness", true, &remap, err);
    if (st != PN_OK) return st;
    double ru = fmax(0.0, u), rv = fmax(0.0, v);
    double au = remap ? sqrt(ru) : ru, av = remap ? sqrt(rv) : rv;
    *roughness = 0.5 * (ru + rv);
    *alpha = 0.5 * (au + av);
    return PN_OK;
}

/* Blinn–Phong exponent for a microfacet alpha; *clamped tells whether the formula was cut. */
static double blinn_exponent(double alpha, bool *clamped) {
    *clamped = false;
    if (!(alpha > 0.0)) {
        *clamped = true;
        return PN_BLINN_MAX_EXPONENT;
    }
    double n = 2.0 / (alpha * alpha) - 2.0;
    if (n > PN_BLINN_MAX_EXPONENT) {
        *clamped = true;
        return PN_BLINN_MAX_EXPONENT;
    }
    if (n < 1.0) {
        *clamped = true;
        return 1.0;
    }
    return n;
}

static double dielectric_f0(double eta) {
    double r = (eta - 1.0) / (eta + 1.0);
    return r * r;
}

static float conductor_f0(float eta, float k) {
    double e = eta, kk = k;
    double num = (e - 1.0) * (e - 1.0) + kk * kk, den = (e + 1.0) * (e + 1.0) + kk * kk;
    return den > 0.0 ? (float)(num / den) : 1.0f;
}

static void describe_roughness(char *out, size_t size, double roughness, double alpha, double n, bool clamped) {
    if (!(alpha > 0.0))
        snprintf(out, size, "(roughness 0: treated as very sharp, n=%g)", n);
    else if (clamped)
        snprintf(out, size, "(roughness %g, alpha %.3g: n clamped to %g)", roughness, alpha, n);
    else
        snprintf(out, size, "(roughness %g, alpha %.3g)", roughness, alpha);
}

/* ---- the types -------------------------------------------------------------------------- */

static void set_lambert(builder *b, pn_texref kd) {
    b->m.kind = PN_MATERIAL_LAMBERT_BLINN;
    b->m.kd = kd;
    b->m.ks = constant_ref(v3(0, 0, 0));
    b->m.exponent = 1.0f;
    char s[128];
    fmt_ref(b->scene, s, sizeof s, kd);
    snprintf(b->model, sizeof b->model, "Lambert kd=%s", s);
}

/* Spectral mode's reflectance spectrum: "reflectance" given as numbers or an .spd file (kept as
 * the scene's pn_spd; RGB mode reads the same parameter's RGB). */
static pn_status reflectance_spectrum(builder *b, pn_err *err) {
    const pn_param *p = find_param(b->ps, "reflectance");
    if (!p || p->type != PN_PT_SPECTRUM) return PN_OK;
    if (p->str_count == 1 && pn_cie_illuminant_named(p->strs[0])) return PN_OK; /* not a reflectance */
    return pn_params_light_spectrum(b->scene, b->ps, "reflectance", &b->m.kd_spd, err);
}

static pn_status map_diffuse(builder *b, pn_err *err) {
    pn_texref kd;
    pn_status st = pn_params_texref(b->scene, b->ps, "reflectance", false, v3(0.5f, 0.5f, 0.5f), &kd, err);
    if (st == PN_OK) st = reflectance_spectrum(b, err);
    if (st != PN_OK) return st;
    set_lambert(b, kd);
    warn_bump(b);
    return PN_OK;
}

/* Cosine-weighted hemispherical average of the Fresnel reflectance from outside,
 * Fbar = integral over mu in [0, 1] of F(mu) 2 mu dmu (midpoint rule, 1024 steps). */
static double hemispherical_fresnel(double eta) {
    const int steps = 1024;
    double sum = 0.0;
    for (int i = 0; i < steps; i++) {
        double mu = ((double)i + 0.5) / steps;
        sum += (double)pn_fresnel_dielectric((float)mu, (float)eta) * 2.0 * mu;
    }
    return sum / steps;
}

static pn_status map_coateddiffuse(builder *b, pn_err *err) {
    pn_texref kd;
    pn_status st = pn_params_texref(b->scene, b->ps, "reflectance", false, v3(0.5f, 0.5f, 0.5f), &kd, err);
    double roughness = 0, alpha = 0, eta = 1.5;
    if (st == PN_OK) st = reflectance_spectrum(b, err);
    if (st == PN_OK) st = read_roughness(b, "", &roughness, &alpha, err);
    if (st == PN_OK) st = pn_params_spectrum_value(b->ps, "eta", 550.0, 1.5, &eta, NULL, err);
    if (st != PN_OK) return st;
    if (!(eta > 0.0)) {
        const pn_param *p = find_param(b->ps, "eta");
        return pn_param_error(p, err, "%s: eta %g must be positive", b->label, eta);
    }
    static const char *const ignored[] = {"thickness", "albedo", "g", "maxdepth", "nsamples"};
    accept_silently(b->ps, ignored, sizeof ignored / sizeof ignored[0]);
    bool clamped = false;
    double n = blinn_exponent(alpha, &clamped);
    float ks = (float)dielectric_f0(eta);
    set_lambert(b, kd);
    /* The base is seen through the coating (scene.h, pn_material.coated). */
    double fbar = hemispherical_fresnel(eta);
    b->m.coated = true;
    b->m.coat_transmission = (float)((1.0 - fbar) * (1.0 - fbar) / (eta * eta));
    b->m.coat_internal = (float)(1.0 - (1.0 - fbar) / (eta * eta));
    b->m.ks = constant_ref(v3(ks, ks, ks));
    b->m.exponent = (float)n;
    size_t len = strlen(b->model);
    snprintf(b->model + len, sizeof b->model - len,
             " under a coating (kd x %.4g / (1 - kd x %.4g)) + Blinn ks=%.4g n=%.5g", (double)b->m.coat_transmission,
             (double)b->m.coat_internal, (double)ks, n);
    describe_roughness(b->note, sizeof b->note, roughness, alpha, n, clamped);
    warn_bump(b);
    return PN_OK;
}

/* The metal table of parameter `name` (def when absent), or NULL (not a named spectrum with a
 * table). */
static const pn_metal_table *metal_table(const pn_params *ps, const char *name, const char *def) {
    const pn_param *p = find_param(ps, name);
    if (!p) return pn_metal_table_named(def);
    if (p->type != PN_PT_SPECTRUM || p->str_count != 1 || p->num_count != 0) return NULL;
    return pn_metal_table_named(p->strs[0]);
}

/* F0 of a conductor from `reflectance` (when the type has one) or eta / k under `prefix`. */
static pn_status conductor_reflectance(builder *b, const char *prefix, bool has_reflectance, pn_texref *f0, char *what,
                                       size_t what_size, pn_err *err) {
    char en[64], kn[64];
    snprintf(en, sizeof en, "%seta", prefix);
    snprintf(kn, sizeof kn, "%sk", prefix);
    const pn_param *refl = has_reflectance ? find_param(b->ps, "reflectance") : NULL;
    if (refl) {
        pn_status st = pn_params_texref(b->scene, b->ps, "reflectance", false, v3(1, 1, 1), f0, err);
        if (st != PN_OK) return st;
        /* eta and k are overridden; they are read so they are not reported as unused. */
        (void)find_param(b->ps, en);
        (void)find_param(b->ps, kn);
        snprintf(what, what_size, "reflectance");
        return PN_OK;
    }
    vec3 cu_eta, cu_k;
    pn_named_spectrum_rgb("metal-Cu-eta", &cu_eta);
    pn_named_spectrum_rgb("metal-Cu-k", &cu_k);
    pn_texref eta_ref, k_ref;
    pn_status st = pn_params_texref_use(b->scene, b->ps, en, false, cu_eta, PN_SPECTRUM_UNBOUNDED, &eta_ref, err);
    if (st == PN_OK) st = pn_params_texref_use(b->scene, b->ps, kn, false, cu_k, PN_SPECTRUM_UNBOUNDED, &k_ref, err);
    if (st != PN_OK) return st;
    bool varies = false;
    vec3 eta = texref_constant(b->scene, eta_ref, cu_eta, &varies);
    vec3 k = texref_constant(b->scene, k_ref, cu_k, &varies);
    if (varies)
        pn_warn_at(b->scene, b->ps->loc,
                   "%s: textured \"%s\" / \"%s\" are not supported; copper is used where they vary", b->label, en, kn);
    *f0 = constant_ref(v3(conductor_f0(eta.x, k.x), conductor_f0(eta.y, k.y), conductor_f0(eta.z, k.z)));
    /* Spectral mode's tables when both eta and k have one: a named spectrum with a table
     * (spectral/metals.h; absent: copper), or a tabulated spectrum given as numbers or an .spd
     * file (kept as a pn_spd, as emission spectra are). */
    const pn_metal_table *et = metal_table(b->ps, en, "metal-Cu-eta"), *kt = metal_table(b->ps, kn, "metal-Cu-k");
    const struct pn_spd *es = NULL, *ks = NULL;
    if (!et) st = pn_params_light_spectrum(b->scene, b->ps, en, &es, err);
    if (st == PN_OK && !kt) st = pn_params_light_spectrum(b->scene, b->ps, kn, &ks, err);
    if (st != PN_OK) return st;
    if ((et || es) && (kt || ks) && !varies) {
        b->m.eta_table = et;
        b->m.k_table = kt;
        b->m.eta_spd = es;
        b->m.k_spd = ks;
    }
    const pn_param *pe = find_param(b->ps, en);
    const char *ename = pe && pe->type == PN_PT_SPECTRUM && pe->str_count == 1 ? pe->strs[0] : NULL;
    if (!pe)
        snprintf(what, what_size, "copper (default)");
    else if (ename)
        snprintf(what, what_size, "eta \"%s\"", ename);
    else
        snprintf(what, what_size, "eta (%.3g, %.3g, %.3g) k (%.3g, %.3g, %.3g)", (double)eta.x, (double)eta.y,
                 (double)eta.z, (double)k.x, (double)k.y, (double)k.z);
    return PN_OK;
}

/* A bare conductor with normal-incidence reflectance f0 (described as `what`): a mirror when
 * smooth, else a Blinn lobe. */
static void set_conductor(builder *b, pn_texref f0, const char *what, double roughness, double alpha) {
    char s[128];
    fmt_ref(b->scene, s, sizeof s, f0);
    if (alpha < PN_SMOOTH_ALPHA) {
        bool varies = false;
        vec3 spec = texref_constant(b->scene, f0, v3(0.9f, 0.9f, 0.9f), &varies);
        if (varies) {
            pn_warn_at(b->scene, b->ps->loc,
                       "%s: a textured reflectance on a smooth conductor is not supported; 0.9 used", b->label);
            fmt_rgb(s, sizeof s, spec);
        }
        b->m.kind = PN_MATERIAL_MIRROR;
        b->m.specular = spec;
        b->m.kd = constant_ref(v3(0, 0, 0));
        b->m.ks = constant_ref(v3(0, 0, 0));
        b->m.exponent = 1.0f;
        snprintf(b->model, sizeof b->model, "mirror specular=%s", s);
        snprintf(b->note, sizeof b->note, "(F0 of %s; smooth: roughness %g)", what, roughness);
    } else {
        bool clamped = false;
        double n = blinn_exponent(alpha, &clamped);
        b->m.kind = PN_MATERIAL_LAMBERT_BLINN;
        b->m.kd = constant_ref(v3(0, 0, 0));
        b->m.ks = f0;
        b->m.exponent = (float)n;
        snprintf(b->model, sizeof b->model, "Blinn ks=%s n=%.5g, kd=0", s, n);
        char r[128];
        describe_roughness(r, sizeof r, roughness, alpha, n, clamped);
        snprintf(b->note, sizeof b->note, "(F0 of %s) %s", what, r);
    }
}

static pn_status map_conductor(builder *b, pn_err *err) {
    double roughness = 0, alpha = 0;
    pn_status st = read_roughness(b, "", &roughness, &alpha, err);
    pn_texref f0;
    char what[160];
    if (st == PN_OK) st = conductor_reflectance(b, "", true, &f0, what, sizeof what, err);
    if (st != PN_OK) return st;
    set_conductor(b, f0, what, roughness, alpha);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_coatedconductor(builder *b, pn_err *err) {
    double roughness = 0, alpha = 0, cr = 0, ca = 0, ieta = 1.5;
    pn_status st = read_roughness(b, "interface.", &roughness, &alpha, err);
    if (st == PN_OK) st = read_roughness(b, "conductor.", &cr, &ca, err);
    if (st == PN_OK) st = pn_params_spectrum_value(b->ps, "interface.eta", 550.0, 1.5, &ieta, NULL, err);
    pn_texref f0;
    char what[160];
    if (st == PN_OK) st = conductor_reflectance(b, "conductor.", true, &f0, what, sizeof what, err);
    if (st != PN_OK) return st;
    static const char *const ignored[] = {"thickness", "albedo", "g", "maxdepth", "nsamples"};
    accept_silently(b->ps, ignored, sizeof ignored / sizeof ignored[0]);
    /* The metal's lobe is seen through the coating: its microfacet spread and the interface's
     * add (as variances of the slope distributions), so either roughness widens the lobe. */
    double alpha_i = alpha;
    alpha = sqrt(alpha_i * alpha_i + ca * ca);
    roughness = 0.5 * (roughness + cr);
    bool clamped = false;
    double n = blinn_exponent(alpha, &clamped);
    b->m.kind = PN_MATERIAL_LAMBERT_BLINN;
    b->m.kd = constant_ref(v3(0, 0, 0));
    b->m.ks = f0;
    b->m.exponent = (float)n;
    char s[128];
    fmt_ref(b->scene, s, sizeof s, f0);
    snprintf(b->model, sizeof b->model, "Blinn ks=%s n=%.5g, kd=0", s, n);
    char r[128];
    describe_roughness(r, sizeof r, roughness, alpha, n, clamped);
    snprintf(b->note, sizeof b->note, "(F0 of the conductor, %s; interface alpha %.3g + conductor alpha %.3g: %s)",
             what, alpha_i, ca, r);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_dielectric(builder *b, pn_err *err) {
    const bool thin = strcmp(b->type, "thindielectric") == 0;
    double eta = 1.5;
    pn_status st = pn_params_spectrum_value(b->ps, "eta", 550.0, 1.5, &eta, NULL, err);
    /* A dielectric pane marked thin (penumbra extension, docs/pbrt-v4-differences.md). */
    bool marked_thin = false;
    if (st == PN_OK && !thin) st = pn_params_bool(b->ps, "thin", false, &marked_thin, err);
    double roughness = 0, alpha = 0;
    if (st == PN_OK && !thin) st = read_roughness(b, "", &roughness, &alpha, err);
    if (st != PN_OK) return st;
    if (!(eta > 0.0))
        return pn_param_error(find_param(b->ps, "eta"), err, "%s: eta %g must be positive", b->label, eta);
    if (alpha >= PN_SMOOTH_ALPHA)
        pn_warn_at(b->scene, b->ps->loc, "%s: rough dielectric (roughness %g) rendered as smooth glass", b->label,
                   roughness);
    b->m.kind = PN_MATERIAL_DIELECTRIC;
    b->m.eta = (float)eta;
    b->m.thin = thin || marked_thin;
    b->m.specular = v3(1, 1, 1);
    b->m.kd = constant_ref(v3(0, 0, 0));
    b->m.ks = constant_ref(v3(0, 0, 0));
    b->m.exponent = 1.0f;
    snprintf(b->model, sizeof b->model, "dielectric eta=%.4g", eta);
    if (alpha >= PN_SMOOTH_ALPHA)
        snprintf(b->note, sizeof b->note, "(roughness %g ignored: smooth)", roughness);
    else if (thin)
        snprintf(b->note, sizeof b->note,
                 "(thin: a refracting surface for eye rays; shadow rays pass it with its slab transmittance)");
    warn_bump(b);
    return PN_OK;
}

/* A new SCALE texture "NAME x s" standing for `in` times s (for material-level scale factors). */
static pn_status scaled_texture(builder *b, pn_texref in, float s, pn_texref *out, pn_err *err) {
    struct pn_scene_s *scene = b->scene;
    const pn_texture *src = &scene->textures[in.texture];
    pn_texture t;
    memset(&t, 0, sizeof t);
    t.kind = PN_TEXTURE_SCALE;
    t.is_float = src->is_float;
    t.image = -1;
    t.su = t.sv = 1.0f;
    t.scale = 1.0f;
    t.a = in;
    t.b = constant_ref(v3(s, s, s));
    t.amount = constant_ref(v3(0, 0, 0));
    char name[300];
    snprintf(name, sizeof name, "%s x %g", src->name ? src->name : "?", (double)s);
    t.name = pn_strdup(name);
    if (!t.name || !pn_grow_for_append((void **)&scene->textures, scene->texture_count, sizeof *scene->textures)) {
        free(t.name);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a texture");
    }
    out->texture = scene->texture_count;
    out->value = v3(0, 0, 0);
    scene->textures[scene->texture_count++] = t;
    return PN_OK;
}

static pn_status map_diffusetransmission(builder *b, pn_err *err) {
    pn_texref kd, kt;
    double scale = 1.0;
    pn_status st = pn_params_texref(b->scene, b->ps, "reflectance", false, v3(0.25f, 0.25f, 0.25f), &kd, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "transmittance", false, v3(0.25f, 0.25f, 0.25f), &kt, err);
    if (st == PN_OK) st = pn_params_float(b->ps, "scale", 1.0, &scale, err);
    if (st != PN_OK) return st;
    if (scale != 1.0) {
        if (kd.texture < 0)
            kd.value = v3_min(v3(1, 1, 1), v3_max(v3(0, 0, 0), v3_scale(kd.value, (float)scale)));
        else if ((st = scaled_texture(b, kd, (float)scale, &kd, err)) != PN_OK)
            return st;
    }
    set_lambert(b, kd);
    pn_warn_at(b->scene, b->ps->loc,
               "%s: diffusetransmission rendered as diffuse reflection; its transmission is dropped", b->label);
    snprintf(b->note, sizeof b->note, "(transmission dropped)");
    warn_bump(b);
    return PN_OK;
}

static pn_status map_substitute(builder *b, pn_err *err) {
    const char *type = b->type;
    pn_texref kd = constant_ref(v3(0.5f, 0.5f, 0.5f));
    pn_status st = PN_OK;
    if (strcmp(type, "hair") == 0) {
        /* pbrt-v4's hair colour input is "reflectance" (pbrt-v3's was "color"). */
        const char *colour = find_param(b->ps, "reflectance") ? "reflectance" : "color";
        if (find_param(b->ps, colour))
            st = pn_params_texref(b->scene, b->ps, colour, false, v3(0.3f, 0.3f, 0.3f), &kd, err);
        else
            kd = constant_ref(v3(0.3f, 0.3f, 0.3f));
    } else if (strcmp(type, "subsurface") == 0) {
        if (find_param(b->ps, "reflectance"))
            st = pn_params_texref(b->scene, b->ps, "reflectance", false, v3(0.5f, 0.5f, 0.5f), &kd, err);
    } else if (b->v3) {
        /* pbrt-v3 translucent / kdsubsurface / fourier / disney: the first colour input given. */
        static const char *const colour_names[] = {"Kd", "color", "reflectance"};
        for (size_t i = 0; i < sizeof colour_names / sizeof colour_names[0]; i++) {
            if (!find_param(b->ps, colour_names[i])) continue;
            st = pn_params_texref(b->scene, b->ps, colour_names[i], false, v3(0.5f, 0.5f, 0.5f), &kd, err);
            break;
        }
    }
    if (st != PN_OK) return st;
    consume_all(b->ps);
    set_lambert(b, kd);
    char s[128];
    fmt_ref(b->scene, s, sizeof s, kd);
    const char *dialect = b->v3 ? "pbrt-v3 " : "";
    pn_warn_at(b->scene, b->ps->loc, "%s: %s%s material is not supported; substituted by a diffuse material kd=%s",
               b->label, dialect, type, s);
    snprintf(b->note, sizeof b->note, "(substitute for an unsupported %s%s material)", dialect, type);
    return PN_OK;
}

static pn_status map_mix_v3(builder *b, pn_err *err);

/* Makes b a copy of material `idx`, described as "material 'NAME' of the mix". */
static void copy_mix_input(builder *b, int idx, const char *name, const char *why) {
    const pn_material *src = &b->scene->materials[idx];
    char *keep_name = b->m.name;
    b->m = *src;
    b->m.name = keep_name;
    b->m.description = NULL;
    /* The chosen material's description without its "NAME: pbrt TYPE -> " head. */
    const char *arrow = src->description ? strstr(src->description, "-> ") : NULL;
    snprintf(b->model, sizeof b->model, "%s", arrow ? arrow + 3 : "?");
    snprintf(b->note, sizeof b->note, "(material '%s' of the mix, %s)", name, why);
}

/* pbrt-v4's MixMaterial: at each hit one of the two materials, the second with probability
 * `amount` (materials.h, ChooseMaterial). names[0] / names[1] are the materials, amount their
 * mixing input (a float texture, or for pbrt-v3 a spectrum whose channel average counts).
 * A constant amount <= 0 or >= 1 is one material, as in pbrt-v4; a mix with an "interface"
 * input cannot be resolved per hit (interface shapes are removed from ray tracing as a whole) and
 * takes the input of larger weight, with a warning. */
static pn_status set_mix(builder *b, const pn_param *where, const char *const names[2], pn_texref amount, pn_err *err) {
    int idx[2];
    for (int i = 0; i < 2; i++) {
        idx[i] = pn_scene_find_material(b->scene, names[i]);
        if (idx[i] < 0) return pn_param_error(where, err, "mix: undefined material \"%s\"", names[i]);
    }
    bool varies = false;
    vec3 c = texref_constant(b->scene, amount, v3(0.5f, 0.5f, 0.5f), &varies);
    double a = ((double)c.x + (double)c.y + (double)c.z) / 3.0;
    char why[96];
    if (!varies && (a <= 0.0 || a >= 1.0)) {
        int pick = a >= 1.0 ? 1 : 0;
        snprintf(why, sizeof why, "amount %g", a);
        copy_mix_input(b, idx[pick], names[pick], why);
        return PN_OK;
    }
    bool interface = b->scene->materials[idx[0]].kind == PN_MATERIAL_INTERFACE ||
                     b->scene->materials[idx[1]].kind == PN_MATERIAL_INTERFACE;
    if (interface) {
        if (varies) a = 0.5;
        int pick = a > 0.5 ? 1 : 0;
        snprintf(why, sizeof why, "probability %g", pick ? a : 1.0 - a);
        copy_mix_input(b, idx[pick], names[pick], why);
        pn_warn_at(b->scene, b->ps->loc,
                   "%s: a mix with an \"interface\" input cannot be chosen per hit; approximated by its input \"%s\"",
                   b->label, names[pick]);
        return PN_OK;
    }
    b->m.kind = PN_MATERIAL_MIX;
    b->m.mix[0] = idx[0];
    b->m.mix[1] = idx[1];
    b->m.mix_amount = amount;
    char s[128];
    fmt_ref(b->scene, s, sizeof s, amount);
    snprintf(b->model, sizeof b->model, "per-hit choice of '%s' and '%s'", names[0], names[1]);
    snprintf(b->note, sizeof b->note, "('%s' with probability %s)", names[1], s);
    return PN_OK;
}

static pn_status map_mix(builder *b, pn_err *err) {
    const pn_param *mp = find_param(b->ps, "materials");
    if (!mp && (find_param(b->ps, "namedmaterial1") || find_param(b->ps, "namedmaterial2"))) return map_mix_v3(b, err);
    if (!mp)
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s:%d:%d: mix material needs \"materials\"",
                          b->ps->loc.file ? b->ps->loc.file : "?", b->ps->loc.line, b->ps->loc.column);
    if (mp->type != PN_PT_STRING || mp->str_count != 2)
        return pn_param_error(mp, err, "\"materials\" of a mix needs two material names");
    pn_texref amount;
    pn_status st = pn_params_texref(b->scene, b->ps, "amount", true, v3(0.5f, 0.5f, 0.5f), &amount, err);
    if (st != PN_OK) return st;
    const char *names[2] = {mp->strs[0], mp->strs[1]};
    st = set_mix(b, mp, names, amount, err);
    if (st != PN_OK) return st;
    warn_bump(b);
    return PN_OK;
}

/* ---- pbrt-v3 material names --------------------------------------------------------------- */

/* pbrt-v3's TrowbridgeReitz RoughnessToAlpha: a quartic in the logarithm of the roughness
 * (floored at 1e-3), evaluated here in Horner form. */
static double v3_roughness_to_alpha(double roughness) {
    double x = log(fmax(roughness, 1e-3));
    return 1.62142 + x * (0.819955 + x * (0.1734 + x * (0.0171201 + x * 0.000640711)));
}

/* Roughness of a pbrt-v3 material, as the average roughness and the average alpha of the two
 * directions. `single`: the type has a "roughness" input (default `def`); `uv`: it has
 * "uroughness" / "vroughness" (default: "roughness", or `def` when there is none).
 * `v_from_u`: a missing vroughness takes uroughness's value (pbrt-v3's uber). */
static pn_status read_roughness_v3(builder *b, bool single, bool uv, bool v_from_u, double def, double *roughness,
                                   double *alpha, pn_err *err) {
    double r = def, u = def, v = def;
    bool has_u = false, has_v = false;
    pn_status st = PN_OK;
    if (single) st = float_input(b, "roughness", def, &r, NULL, err);
    if (st == PN_OK && uv) st = float_input(b, "uroughness", r, &u, &has_u, err);
    if (st == PN_OK && uv) st = float_input(b, "vroughness", r, &v, &has_v, err);
    if (st != PN_OK) return st;
    if (!has_u) u = r;
    if (!has_v) v = v_from_u ? u : r;
    bool remap = true;
    st = pn_params_bool(b->ps, "remaproughness", true, &remap, err);
    if (st != PN_OK) return st;
    double ru = fmax(0.0, u), rv = fmax(0.0, v);
    double au = remap ? v3_roughness_to_alpha(ru) : ru, av = remap ? v3_roughness_to_alpha(rv) : rv;
    *roughness = 0.5 * (ru + rv);
    *alpha = 0.5 * (au + av);
    return PN_OK;
}

/* Adds a Blinn lobe ks with the exponent for `alpha` to the Lambert model set before. */
static void add_blinn(builder *b, pn_texref ks, double roughness, double alpha) {
    bool clamped = false;
    double n = blinn_exponent(alpha, &clamped);
    b->m.ks = ks;
    b->m.exponent = (float)n;
    char s[128];
    fmt_ref(b->scene, s, sizeof s, ks);
    size_t len = strlen(b->model);
    snprintf(b->model + len, sizeof b->model - len, " + Blinn ks=%s n=%.5g", s, n);
    char r[160];
    describe_roughness(r, sizeof r, roughness, alpha, n, clamped);
    add_note(b, "%s", r);
}

/* pbrt-v3's index of refraction: "eta", else its older name "index" (default 1.5). pbrt-v3
 * reads a float or float texture; a pbrt-v4 style spectrum is taken at 550 nm. */
static pn_status read_v3_eta(builder *b, double *eta, bool *found, pn_err *err) {
    *eta = 1.5;
    *found = false;
    const char *name = "eta";
    const pn_param *p = find_param(b->ps, name);
    if (!p) {
        name = "index";
        p = find_param(b->ps, name);
    }
    if (!p) return PN_OK;
    *found = true;
    pn_status st = p->type == PN_PT_TEXTURE ? float_input(b, name, 1.5, eta, NULL, err)
                                            : pn_params_spectrum_value(b->ps, name, 550.0, 1.5, eta, NULL, err);
    if (st != PN_OK) return st;
    if (!(*eta > 0.0)) return pn_param_error(p, err, "%s: %s %g must be positive", b->label, name, *eta);
    return PN_OK;
}

/* One colour a model needs as a constant (a mirror or glass tint): a texture that is not constant
 * gives `fallback`, with a warning at the parameter. */
static vec3 constant_tint(builder *b, const char *name, pn_texref r, vec3 fallback) {
    bool varies = false;
    vec3 c = texref_constant(b->scene, r, fallback, &varies);
    if (varies) {
        const pn_param *p = find_param(b->ps, name);
        char s[64];
        fmt_rgb(s, sizeof s, fallback);
        pn_warn_at(b->scene, p ? p->loc : b->ps->loc, "%s: a varying texture \"%s\" is not supported here; %s is used",
                   b->label, name, s);
    }
    return c;
}

static bool is_white(vec3 c) {
    return c.x == 1.0f && c.y == 1.0f && c.z == 1.0f;
}

static pn_status map_v3_matte(builder *b, pn_err *err) {
    pn_texref kd;
    double sigma = 0.0;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kd", false, v3(0.5f, 0.5f, 0.5f), &kd, err);
    if (st == PN_OK) st = float_input(b, "sigma", 0.0, &sigma, NULL, err);
    if (st != PN_OK) return st;
    set_lambert(b, kd);
    if (sigma > 0.0) add_note(b, "(Oren-Nayar sigma %g ignored: rendered Lambertian)", sigma);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_plastic(builder *b, pn_err *err) {
    pn_texref kd, ks;
    double roughness = 0, alpha = 0;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kd", false, v3(0.25f, 0.25f, 0.25f), &kd, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Ks", false, v3(0.25f, 0.25f, 0.25f), &ks, err);
    if (st == PN_OK) st = read_roughness_v3(b, true, false, false, 0.1, &roughness, &alpha, err);
    if (st != PN_OK) return st;
    set_lambert(b, kd);
    add_blinn(b, ks, roughness, alpha);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_substrate(builder *b, pn_err *err) {
    pn_texref kd, ks;
    double roughness = 0, alpha = 0;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kd", false, v3(0.5f, 0.5f, 0.5f), &kd, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Ks", false, v3(0.5f, 0.5f, 0.5f), &ks, err);
    if (st == PN_OK) st = read_roughness_v3(b, false, true, false, 0.1, &roughness, &alpha, err);
    if (st != PN_OK) return st;
    set_lambert(b, kd);
    add_blinn(b, ks, roughness, alpha);
    add_note(b, "(Ks as the reflectance at normal incidence)");
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_uber(builder *b, pn_err *err) {
    pn_texref kd, ks, kr, kt, opacity;
    double roughness = 0, alpha = 0, eta = 1.5;
    bool has_eta = false;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kd", false, v3(0.25f, 0.25f, 0.25f), &kd, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Ks", false, v3(0.25f, 0.25f, 0.25f), &ks, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Kr", false, v3(0, 0, 0), &kr, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Kt", false, v3(0, 0, 0), &kt, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "opacity", false, v3(1, 1, 1), &opacity, err);
    if (st == PN_OK) st = read_roughness_v3(b, true, true, true, 0.1, &roughness, &alpha, err);
    if (st == PN_OK) st = read_v3_eta(b, &eta, &has_eta, err);
    if (st != PN_OK) return st;
    set_lambert(b, kd);
    add_blinn(b, ks, roughness, alpha);
    /* The perfectly specular lobes have no place in a Lambert + Blinn model. */
    const char *lobe_names[2] = {"Kr", "Kt"};
    const char *lobe_what[2] = {"specular reflection", "specular transmission"};
    pn_texref lobes[2] = {kr, kt};
    for (int i = 0; i < 2; i++) {
        bool varies = false;
        vec3 c = texref_constant(b->scene, lobes[i], v3(1, 1, 1), &varies);
        if (!varies && v3_is_zero(c)) continue;
        const pn_param *p = find_param(b->ps, lobe_names[i]);
        char s[128];
        fmt_ref(b->scene, s, sizeof s, lobes[i]);
        pn_warn_at(b->scene, p ? p->loc : b->ps->loc, "%s: uber's %s \"%s\" = %s is dropped", b->label, lobe_what[i],
                   lobe_names[i], s);
        add_note(b, "(%s %s dropped)", lobe_names[i], s);
    }
    bool op_varies = false;
    vec3 op = texref_constant(b->scene, opacity, v3(1, 1, 1), &op_varies);
    if (op_varies || fminf(op.x, fminf(op.y, op.z)) < 1.0f) {
        const pn_param *p = find_param(b->ps, "opacity");
        char s[128];
        fmt_ref(b->scene, s, sizeof s, opacity);
        pn_warn_at(b->scene, p ? p->loc : b->ps->loc, "%s: \"opacity\" %s (below 1) is ignored; rendered opaque",
                   b->label, s);
        add_note(b, "(opacity %s ignored)", s);
    }
    if (has_eta) add_note(b, "(eta %g not used)", eta);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_glass(builder *b, pn_err *err) {
    pn_texref kr, kt;
    double eta = 1.5, roughness = 0, alpha = 0;
    bool has_eta = false;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kr", false, v3(1, 1, 1), &kr, err);
    if (st == PN_OK) st = pn_params_texref(b->scene, b->ps, "Kt", false, v3(1, 1, 1), &kt, err);
    if (st == PN_OK) st = read_v3_eta(b, &eta, &has_eta, err);
    if (st == PN_OK) st = read_roughness_v3(b, false, true, false, 0.0, &roughness, &alpha, err);
    if (st != PN_OK) return st;
    vec3 r = constant_tint(b, "Kr", kr, v3(1, 1, 1));
    vec3 t = constant_tint(b, "Kt", kt, v3(1, 1, 1));
    b->m.kind = PN_MATERIAL_DIELECTRIC;
    b->m.eta = (float)eta;
    b->m.kd = constant_ref(v3(0, 0, 0));
    b->m.ks = constant_ref(v3(0, 0, 0));
    b->m.exponent = 1.0f;
    b->m.specular = v3(1, 1, 1);
    char rs[64], ts[64];
    fmt_rgb(rs, sizeof rs, r);
    fmt_rgb(ts, sizeof ts, t);
    if (v3_is_zero(r)) {
        /* Transmission only in pbrt-v3; penumbra's glass reflects anyway, so Kt is the tint. */
        b->m.specular = t;
        if (!is_white(t))
            add_note(b, "(specular tint Kt=%s; Kr=0 not honoured: glass always reflects)", ts);
        else
            add_note(b, "(Kr=0 not honoured: glass always reflects)");
        pn_warn_at(b->scene, b->ps->loc, "%s: glass with Kr = 0 still reflects in penumbra", b->label);
    } else {
        if (!is_white(r)) {
            b->m.specular = r;
            add_note(b, "(specular tint Kr=%s)", rs);
        }
        if (!is_white(t)) {
            const pn_param *p = find_param(b->ps, "Kt");
            pn_warn_at(b->scene, p ? p->loc : b->ps->loc, "%s: the transmission tint Kt = %s of glass is dropped",
                       b->label, ts);
            add_note(b, "(Kt=%s dropped)", ts);
        }
    }
    if (roughness > 0.0) {
        pn_warn_at(b->scene, b->ps->loc, "%s: rough glass (roughness %g) rendered as smooth glass", b->label,
                   roughness);
        add_note(b, "(roughness %g ignored: smooth)", roughness);
    }
    snprintf(b->model, sizeof b->model, "dielectric eta=%.4g", eta);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_metal(builder *b, pn_err *err) {
    double roughness = 0, alpha = 0;
    pn_status st = read_roughness_v3(b, true, true, false, 0.01, &roughness, &alpha, err);
    pn_texref f0;
    char what[160];
    if (st == PN_OK) st = conductor_reflectance(b, "", false, &f0, what, sizeof what, err);
    if (st != PN_OK) return st;
    set_conductor(b, f0, what, roughness, alpha);
    warn_bump(b);
    return PN_OK;
}

static pn_status map_v3_mirror(builder *b, pn_err *err) {
    pn_texref kr;
    pn_status st = pn_params_texref(b->scene, b->ps, "Kr", false, v3(0.9f, 0.9f, 0.9f), &kr, err);
    if (st != PN_OK) return st;
    vec3 spec = constant_tint(b, "Kr", kr, v3(0.9f, 0.9f, 0.9f));
    b->m.kind = PN_MATERIAL_MIRROR;
    b->m.specular = spec;
    b->m.kd = constant_ref(v3(0, 0, 0));
    b->m.ks = constant_ref(v3(0, 0, 0));
    b->m.exponent = 1.0f;
    char s[64];
    fmt_rgb(s, sizeof s, spec);
    snprintf(b->model, sizeof b->model, "mirror specular=%s", s);
    warn_bump(b);
    return PN_OK;
}

/* pbrt-v3's mix: "namedmaterial1" / "namedmaterial2", with "amount" (a spectrum, default 0.5)
 * weighting the first one; resolved per hit like pbrt-v4's mix (set_mix). */
static pn_status map_mix_v3(builder *b, pn_err *err) {
    b->v3 = true;
    const char *names[2] = {NULL, NULL};
    pn_status st = pn_params_string(b->ps, "namedmaterial1", NULL, &names[0], err);
    if (st == PN_OK) st = pn_params_string(b->ps, "namedmaterial2", NULL, &names[1], err);
    if (st != PN_OK) return st;
    for (int i = 0; i < 2; i++) {
        if (names[i]) continue;
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s:%d:%d: pbrt-v3 mix material needs \"namedmaterial%d\"",
                          b->ps->loc.file ? b->ps->loc.file : "?", b->ps->loc.line, b->ps->loc.column, i + 1);
    }
    pn_texref amount_ref;
    st = pn_params_texref(b->scene, b->ps, "amount", false, v3(0.5f, 0.5f, 0.5f), &amount_ref, err);
    if (st != PN_OK) return st;
    for (int i = 0; i < 2; i++) {
        if (pn_scene_find_material(b->scene, names[i]) >= 0) continue;
        char pname[32];
        snprintf(pname, sizeof pname, "namedmaterial%d", i + 1);
        return pn_param_error(find_param(b->ps, pname), err, "mix: undefined material \"%s\"", names[i]);
    }
    /* pbrt-v3 weights the first material by amount: the per-hit choice takes it with
     * probability amount, i.e. the second of set_mix's pair is namedmaterial1. The expected
     * BSDF is pbrt-v3's blend amount * f1 + (1 - amount) * f2. */
    const char *swapped[2] = {names[1], names[0]};
    return set_mix(b, find_param(b->ps, "namedmaterial1"), swapped, amount_ref, err);
}

/* ---- entry points ----------------------------------------------------------------------- */

/* Interface materials bound media; for rendering they are invisible. */
static pn_status map_interface(builder *b, pn_err *err) {
    (void)err;
    b->m.kind = PN_MATERIAL_INTERFACE;
    snprintf(b->model, sizeof b->model, "interface (invisible)");
    return PN_OK;
}

/* Every pbrt material type penumbra reads, the pbrt-v4 names and then the pbrt-v3 ones. */
typedef struct material_entry {
    const char *type;
    bool v3;
    pn_status (*map)(builder *b, pn_err *err);
} material_entry;

static const material_entry material_table[] = {
    {"diffuse", false, map_diffuse},
    {"coateddiffuse", false, map_coateddiffuse},
    {"conductor", false, map_conductor},
    {"coatedconductor", false, map_coatedconductor},
    {"dielectric", false, map_dielectric},
    {"thindielectric", false, map_dielectric},
    {"diffusetransmission", false, map_diffusetransmission},
    {"measured", false, map_substitute},
    {"hair", false, map_substitute},
    {"subsurface", false, map_substitute},
    {"mix", false, map_mix},
    {"interface", false, map_interface},
    {"none", false, map_interface},
    {"matte", true, map_v3_matte},
    {"plastic", true, map_v3_plastic},
    {"substrate", true, map_v3_substrate},
    {"uber", true, map_v3_uber},
    {"glass", true, map_v3_glass},
    {"metal", true, map_v3_metal},
    {"mirror", true, map_v3_mirror},
    {"translucent", true, map_substitute},
    {"kdsubsurface", true, map_substitute},
    {"fourier", true, map_substitute},
    {"disney", true, map_substitute},
};

pn_status pn_material_from_pbrt(struct pn_scene_s *scene, const char *type, const char *name, const pn_params *ps,
                                int *out, pn_err *err) {
    if (out) *out = -1;
    if (!name) name = "";
    builder b;
    memset(&b, 0, sizeof b);
    b.scene = scene;
    b.ps = ps;
    char label[256];
    if (name[0])
        snprintf(label, sizeof label, "material \"%s\"", name);
    else
        snprintf(label, sizeof label, "material");
    b.label = label;
    b.m.kind = PN_MATERIAL_LAMBERT_BLINN;
    b.m.kd = constant_ref(v3(0, 0, 0));
    b.m.ks = constant_ref(v3(0, 0, 0));
    b.m.exponent = 1.0f;
    b.m.specular = v3(0, 0, 0);
    b.m.eta = 1.0f;
    b.m.name = NULL;

    const material_entry *e = NULL;
    for (size_t i = 0; i < sizeof material_table / sizeof material_table[0]; i++)
        if (strcmp(type, material_table[i].type) == 0) e = &material_table[i];
    if (!e)
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s:%d:%d: unknown material type \"%s\"",
                          ps->loc.file ? ps->loc.file : "?", ps->loc.line, ps->loc.column, type);
    b.type = type;
    b.v3 = e->v3;
    pn_status st = e->map(&b, err);
    if (st != PN_OK) return st;

    char head[256];
    if (name[0])
        snprintf(head, sizeof head, "%s", name);
    else if (ps->loc.file)
        snprintf(head, sizeof head, "(anonymous, %s:%d)", ps->loc.file, ps->loc.line);
    else
        snprintf(head, sizeof head, "(default material)");
    size_t need = strlen(head) + strlen(type) + strlen(b.model) + strlen(b.note) + 32;
    char *desc = malloc(need);
    b.m.name = pn_strdup(name);
    if (!desc || !b.m.name ||
        !pn_grow_for_append((void **)&scene->materials, scene->material_count, sizeof *scene->materials)) {
        free(desc);
        free(b.m.name);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a material");
    }
    snprintf(desc, need, "%s: %s %s -> %s%s%s", head, b.v3 ? "pbrt-v3" : "pbrt", type, b.model, b.note[0] ? " " : "",
             b.note);
    b.m.description = desc;
    scene->materials[scene->material_count] = b.m;
    if (out) *out = scene->material_count;
    scene->material_count++;
    return PN_OK;
}

int pn_scene_find_material(const struct pn_scene_s *scene, const char *name) {
    if (!name || !name[0]) return -1;
    for (int i = scene->material_count - 1; i >= 0; i--)
        if (scene->materials[i].name && strcmp(scene->materials[i].name, name) == 0) return i;
    return -1;
}
