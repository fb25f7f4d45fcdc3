/* test_materials.c — the pbrt-v4 material, spectrum, texture and light builders against closed
 * forms: material mapping and descriptions (pbrt-v4 types and the pbrt-v3 names with their
 * roughness remapping), conductor Fresnel, blackbody and constant spectra,
 * point/spot/area power normalisation, bilinear image lookups with wrap modes. Parameter lists
 * are assembled by hand. */
#include "harness.h"

#include "io/image.h"
#include "shade/bsdf.h"
#include "scene/build.h"
#include "spectral/transport.h"

#include <unistd.h>

/* ---- building parameter lists and scenes ---------------------------------------------------- */

static char *dupstr(const char *s) {
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    memcpy(d, s, n);
    return d;
}

static pn_params make_params(void) {
    pn_params ps;
    memset(&ps, 0, sizeof ps);
    ps.base_dir = "";
    ps.loc.file = "scene.pbrt";
    ps.loc.line = 12;
    ps.loc.column = 3;
    return ps;
}

static pn_param *add_param(pn_params *ps, pn_param_type type, const char *name) {
    ps->items = realloc(ps->items, (size_t)(ps->count + 1) * sizeof *ps->items);
    pn_param *p = &ps->items[ps->count++];
    memset(p, 0, sizeof *p);
    p->type = type;
    p->name = dupstr(name);
    p->loc.file = "scene.pbrt";
    p->loc.line = 13 + ps->count;
    p->loc.column = 5;
    return p;
}

static void add_nums(pn_params *ps, pn_param_type type, const char *name, int n, const double *v) {
    pn_param *p = add_param(ps, type, name);
    p->nums = malloc((size_t)n * sizeof *p->nums);
    memcpy(p->nums, v, (size_t)n * sizeof *v);
    p->num_count = n;
}

static void add_float(pn_params *ps, const char *name, double v) {
    add_nums(ps, PN_PT_FLOAT, name, 1, &v);
}

static void add_bool(pn_params *ps, const char *name, bool b) {
    double v = b ? 1.0 : 0.0;
    add_nums(ps, PN_PT_BOOL, name, 1, &v);
}

static void add_rgb(pn_params *ps, const char *name, double r, double g, double b) {
    double v[3] = {r, g, b};
    add_nums(ps, PN_PT_RGB, name, 3, v);
}

static void add_str(pn_params *ps, pn_param_type type, const char *name, const char *s) {
    pn_param *p = add_param(ps, type, name);
    p->strs = malloc(sizeof *p->strs);
    p->strs[0] = dupstr(s);
    p->str_count = 1;
}

static void add_strs2(pn_params *ps, const char *name, const char *a, const char *b) {
    pn_param *p = add_param(ps, PN_PT_STRING, name);
    p->strs = malloc(2 * sizeof *p->strs);
    p->strs[0] = dupstr(a);
    p->strs[1] = dupstr(b);
    p->str_count = 2;
}

static void silent_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static struct pn_scene_s *new_scene(void) {
    struct pn_scene_s *s = calloc(1, sizeof *s);
    s->ctx = pn_context_new();
    pn_context_set_log(s->ctx, silent_log, NULL);
    return s;
}

static void free_scene(struct pn_scene_s *s) {
    for (int i = 0; i < s->material_count; i++) {
        free(s->materials[i].name);
        free(s->materials[i].description);
    }
    for (int i = 0; i < s->texture_count; i++) free(s->textures[i].name);
    for (int i = 0; i < s->image_count; i++) {
        free(s->images[i].rgb);
        free(s->images[i].path);
    }
    for (int i = 0; i < s->light_def_count; i++) free(s->light_defs[i].source);
    for (int i = 0; i < s->mipmap_count; i++) pn_mipmap_free(&s->mipmaps[i]);
    for (int i = 0; i < s->spd_count; i++) pn_spd_free(s->spds[i]);
    free(s->mipmaps);
    free(s->spds);
    free(s->materials);
    free(s->textures);
    free(s->images);
    free(s->light_defs);
    pn_warning_list_free(&s->warnings);
    pn_context_free(s->ctx);
    free(s);
}

static bool has_warning(const struct pn_scene_s *s, const char *needle) {
    for (int i = 0; i < s->warnings.count; i++)
        if (strstr(s->warnings.items[i], needle)) return true;
    return false;
}

/* Builds a material of `type` from ps; returns its index (or -1, failing the test). */
static int build_material(struct pn_scene_s *s, const char *type, const char *name, pn_params *ps) {
    pn_err err;
    pn_err_init(&err);
    int idx = -1;
    pn_status st = pn_material_from_pbrt(s, type, name, ps, &idx, &err);
    CHECK_MSG(st == PN_OK, "%s", err.message);
    pn_params_free(ps);
    return st == PN_OK ? idx : -1;
}

static double f0_conductor(double eta, double k) {
    return ((eta - 1) * (eta - 1) + k * k) / ((eta + 1) * (eta + 1) + k * k);
}

/* ---- materials ---------------------------------------------------------------------------- */

static void test_diffuse_default(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "diffuse", "Wall", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK(m->kd.texture < 0);
        CHECK_NEAR(m->kd.value.x, 0.5, 1e-6);
        CHECK_NEAR(m->kd.value.z, 0.5, 1e-6);
        CHECK(v3_is_zero(m->ks.value) && m->ks.texture < 0);
        CHECK_STR_CONTAINS(m->description, "Wall: pbrt diffuse -> Lambert kd=0.5");
        CHECK(pn_scene_find_material(s, "Wall") == i);
        CHECK(pn_scene_find_material(s, "Other") == -1);
    }
    /* An albedo above 1 is clamped with a warning. */
    ps = make_params();
    add_rgb(&ps, "reflectance", 1.5, 0.2, 0.1);
    i = build_material(s, "diffuse", "", &ps);
    if (i >= 0) {
        CHECK_NEAR(s->materials[i].kd.value.x, 1.0, 1e-6);
        CHECK_NEAR(s->materials[i].kd.value.y, 0.2, 1e-6);
        CHECK(has_warning(s, "clamped"));
        CHECK_STR_CONTAINS(s->materials[i].description, "(anonymous, scene.pbrt:12)");
    }
    free_scene(s);
}

static void test_coateddiffuse(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    add_rgb(&ps, "reflectance", 0.2, 0.3, 0.4);
    add_float(&ps, "roughness", 0.1);
    int i = build_material(s, "coateddiffuse", "Floor", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->kd.value.y, 0.3, 1e-6);
        CHECK_NEAR(m->ks.value.x, 0.04, 1e-6);
        /* remaproughness: alpha = sqrt(0.1), n = 2 / alpha^2 - 2 = 18 */
        CHECK_NEAR(m->exponent, 18.0, 1e-3);
        CHECK_STR_CONTAINS(m->description, "Floor: pbrt coateddiffuse -> Lambert kd=(0.2, 0.3, 0.4) under a coating");
        CHECK_STR_CONTAINS(m->description, "+ Blinn ks=0.04 n=18");
        /* The base seen through an eta = 1.5 coating: the external hemispherical Fresnel
         * reflectance of n = 1.5 is 0.0918, so T = (1 - 0.0918)^2 / 2.25 = 0.3666 and the
         * internal diffuse reflectance is 1 - 0.9082 / 2.25 = 0.5963 (the classic 0.596). */
        CHECK(m->coated);
        CHECK_NEAR(m->coat_transmission, 0.3666, 5e-4);
        CHECK_NEAR(m->coat_internal, 0.5963, 5e-4);
        vec3 seen = pn_coated_diffuse(v3(0.5f, 0.5f, 0.5f), m->coat_transmission, m->coat_internal);
        CHECK_NEAR(seen.x, 0.5 * 0.3666 / (1.0 - 0.5 * 0.5963), 1e-3);
    }
    ps = make_params();
    add_float(&ps, "uroughness", 0.05);
    add_float(&ps, "vroughness", 0.15);
    add_bool(&ps, "remaproughness", false);
    add_float(&ps, "eta", 1.33);
    i = build_material(s, "coateddiffuse", "B", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        double f0 = pow((1.33 - 1) / (1.33 + 1), 2);
        CHECK_NEAR(m->ks.value.z, f0, 1e-6);
        CHECK_NEAR(m->exponent, 2.0 / (0.1 * 0.1) - 2.0, 1e-2);
        CHECK_NEAR(m->kd.value.x, 0.5, 1e-6);
    }
    ps = make_params(); /* roughness 0: very sharp */
    i = build_material(s, "coateddiffuse", "C", &ps);
    if (i >= 0) {
        CHECK_NEAR(s->materials[i].exponent, 10000.0, 1e-3);
        CHECK_STR_CONTAINS(s->materials[i].description, "very sharp");
    }
    free_scene(s);
}

static void test_conductor(void) {
    struct pn_scene_s *s = new_scene();
    vec3 eta, k;
    CHECK(pn_named_spectrum_rgb("metal-Cu-eta", &eta));
    CHECK(pn_named_spectrum_rgb("metal-Cu-k", &k));
    /* Named copper, smooth: mirror with the normal-incidence Fresnel reflectance. */
    pn_params ps = make_params();
    add_str(&ps, PN_PT_SPECTRUM, "eta", "metal-Cu-eta");
    add_str(&ps, PN_PT_SPECTRUM, "k", "metal-Cu-k");
    add_float(&ps, "roughness", 0.0);
    int i = build_material(s, "conductor", "Copper", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_MIRROR);
        CHECK_NEAR(m->specular.x, f0_conductor(eta.x, k.x), 1e-5);
        CHECK_NEAR(m->specular.y, f0_conductor(eta.y, k.y), 1e-5);
        CHECK_NEAR(m->specular.z, f0_conductor(eta.z, k.z), 1e-5);
        CHECK(m->specular.x > m->specular.z); /* copper is reddish */
        CHECK_STR_CONTAINS(m->description, "Copper: pbrt conductor -> mirror");
    }
    /* The default conductor is copper too. */
    ps = make_params();
    i = build_material(s, "conductor", "Default", &ps);
    if (i >= 0) CHECK_NEAR(s->materials[i].specular.x, f0_conductor(eta.x, k.x), 1e-5);
    /* Explicit rgb eta / k, rough: Blinn lobe, kd = 0. */
    ps = make_params();
    add_rgb(&ps, "eta", 1.65746, 0.880369, 0.521229);
    add_rgb(&ps, "k", 9.223869, 6.269523, 4.837001);
    add_float(&ps, "uroughness", 0.2);
    add_float(&ps, "vroughness", 0.2);
    i = build_material(s, "conductor", "Steel", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK(v3_is_zero(m->kd.value));
        CHECK_NEAR(m->ks.value.x, f0_conductor(1.65746, 9.223869), 1e-5);
        CHECK_NEAR(m->ks.value.y, f0_conductor(0.880369, 6.269523), 1e-5);
        CHECK_NEAR(m->ks.value.z, f0_conductor(0.521229, 4.837001), 1e-5);
        CHECK_NEAR(m->exponent, 2.0 / 0.2 - 2.0, 1e-3);
    }
    /* "reflectance" overrides eta / k. */
    ps = make_params();
    add_rgb(&ps, "reflectance", 0.9, 0.8, 0.7);
    i = build_material(s, "conductor", "R", &ps);
    if (i >= 0) {
        CHECK(s->materials[i].kind == PN_MATERIAL_MIRROR);
        CHECK_NEAR(s->materials[i].specular.y, 0.8, 1e-6);
    }
    /* coatedconductor: Blinn from the conductor's F0 and both roughnesses: alpha^2 = 0.02 +
     * 0.002 (remapped alpha = sqrt(roughness)). */
    ps = make_params();
    add_str(&ps, PN_PT_SPECTRUM, "conductor.eta", "metal-Cu-eta");
    add_str(&ps, PN_PT_SPECTRUM, "conductor.k", "metal-Cu-k");
    add_float(&ps, "interface.roughness", 0.02);
    add_float(&ps, "conductor.roughness", 0.002);
    i = build_material(s, "coatedconductor", "CC", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->ks.value.x, f0_conductor(eta.x, k.x), 1e-5);
        CHECK_NEAR(m->exponent, 2.0 / 0.022 - 2.0, 1e-2);
    }
    free_scene(s);
}

static void test_dielectric_mix_interface(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    add_float(&ps, "eta", 1.33);
    int glass = build_material(s, "dielectric", "Water", &ps);
    if (glass >= 0) {
        CHECK(s->materials[glass].kind == PN_MATERIAL_DIELECTRIC);
        CHECK_NEAR(s->materials[glass].eta, 1.33, 1e-6);
        CHECK_NEAR(s->materials[glass].specular.y, 1.0, 1e-6);
    }
    ps = make_params();
    add_str(&ps, PN_PT_SPECTRUM, "eta", "glass-BK7");
    add_float(&ps, "roughness", 0.3);
    int bk7 = build_material(s, "dielectric", "BK7", &ps);
    if (bk7 >= 0) {
        CHECK_NEAR(s->materials[bk7].eta, 1.5185, 1e-3);
        CHECK(has_warning(s, "rough dielectric"));
    }
    ps = make_params();
    double spd[4] = {400, 1.6, 700, 1.4};
    add_nums(&ps, PN_PT_SPECTRUM, "eta", 4, spd);
    int i = build_material(s, "dielectric", "Spd", &ps);
    if (i >= 0) CHECK_NEAR(s->materials[i].eta, 1.6 - 0.2 * (150.0 / 300.0), 1e-4);

    ps = make_params();
    int diffuse = build_material(s, "diffuse", "D", &ps);
    ps = make_params();
    add_strs2(&ps, "materials", "D", "Water");
    add_float(&ps, "amount", 0.7);
    i = build_material(s, "mix", "Mix", &ps);
    if (i >= 0 && diffuse >= 0) {
        /* pbrt-v4 chooses per hit: a MIX record with the second input at probability 0.7. */
        CHECK(s->materials[i].kind == PN_MATERIAL_MIX);
        CHECK(s->materials[i].mix[0] == diffuse);
        CHECK(s->materials[i].kind != PN_MATERIAL_MIX ||
              s->materials[s->materials[i].mix[1]].kind == PN_MATERIAL_DIELECTRIC);
        CHECK_NEAR(s->materials[i].mix_amount.value.x, 0.7, 1e-6);
        CHECK_STR_CONTAINS(s->materials[i].description, "Mix: pbrt mix -> per-hit choice of 'D' and 'Water'");
    }
    ps = make_params();
    i = build_material(s, "interface", "I", &ps);
    if (i >= 0) CHECK(s->materials[i].kind == PN_MATERIAL_INTERFACE);

    ps = make_params();
    add_rgb(&ps, "reflectance", 0.4, 0.4, 0.4);
    i = build_material(s, "diffusetransmission", "T", &ps);
    if (i >= 0) {
        CHECK_NEAR(s->materials[i].kd.value.x, 0.4, 1e-6);
        CHECK(has_warning(s, "transmission is dropped"));
    }
    free_scene(s);
}

static void test_unknown_material(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    pn_err err;
    pn_err_init(&err);
    int idx = 7;
    pn_status st = pn_material_from_pbrt(s, "foo", "X", &ps, &idx, &err);
    CHECK(st == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:12:3: unknown material type \"foo\"");
    CHECK(s->material_count == 0);
    pn_params_free(&ps);

    /* A texture name that is not defined is an error at the parameter. */
    ps = make_params();
    add_str(&ps, PN_PT_TEXTURE, "reflectance", "nope");
    pn_err_init(&err);
    st = pn_material_from_pbrt(s, "diffuse", "Y", &ps, &idx, &err);
    CHECK(st == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:14:5:");
    CHECK_STR_CONTAINS(err.message, "nope");
    pn_params_free(&ps);
    free_scene(s);
}

/* ---- pbrt-v3 material names ------------------------------------------------------------------ */

/* pbrt-v3's roughness remapping written out term by term (the closed form the mapping must match). */
static double v3_alpha(double roughness) {
    double x = log(roughness < 1e-3 ? 1e-3 : roughness);
    return 1.62142 + 0.819955 * x + 0.1734 * x * x + 0.0171201 * x * x * x + 0.000640711 * x * x * x * x;
}

/* The Blinn exponent rule of materials.c: n = 2 / alpha^2 - 2 within [1, 10000]. */
static double blinn_n(double alpha) {
    double n = 2.0 / (alpha * alpha) - 2.0;
    return n < 1.0 ? 1.0 : n > 10000.0 ? 10000.0 : n;
}

/* Builds a material without freeing ps (so the caller can look at which parameters were read). */
static int build_keep(struct pn_scene_s *s, const char *type, const char *name, pn_params *ps) {
    pn_err err;
    pn_err_init(&err);
    int idx = -1;
    pn_status st = pn_material_from_pbrt(s, type, name, ps, &idx, &err);
    CHECK_MSG(st == PN_OK, "%s", err.message);
    return st == PN_OK ? idx : -1;
}

static bool param_used(const pn_params *ps, const char *name) {
    for (int i = 0; i < ps->count; i++)
        if (strcmp(ps->items[i].name, name) == 0) return ps->items[i].used;
    return false;
}

/* Building `type` from ps must fail with an error at `where` ("scene.pbrt:LINE:5:") naming `param`;
 * no material is added. Frees ps. */
static void expect_param_error(struct pn_scene_s *s, const char *type, pn_params *ps, const char *where,
                               const char *param) {
    pn_err err;
    pn_err_init(&err);
    int before = s->material_count, idx = 7;
    pn_status st = pn_material_from_pbrt(s, type, "Bad", ps, &idx, &err);
    CHECK_MSG(st == PN_ERROR_BAD_INPUT, "%s: status %d", type, (int)st);
    CHECK_STR_CONTAINS(err.message, where);
    CHECK_STR_CONTAINS(err.message, param);
    CHECK(s->material_count == before);
    pn_params_free(ps);
}

static void test_v3_remap_closed_form(void) {
    /* Reference values of the quartic, computed independently. */
    CHECK_NEAR(v3_alpha(0.1), 0.4617600320, 1e-8);
    CHECK_NEAR(v3_alpha(0.5), 1.1308275394, 1e-8);
    CHECK_NEAR(v3_alpha(0.0), v3_alpha(1e-3), 1e-12);
    CHECK_NEAR(blinn_n(v3_alpha(0.1)), 7.3798807, 1e-5);
    CHECK_NEAR(blinn_n(v3_alpha(0.5)), 1.0, 0.0);
}

static void test_v3_matte(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "matte", "M", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK(m->kd.texture < 0);
        CHECK_NEAR(m->kd.value.x, 0.5, 1e-6);
        CHECK(v3_is_zero(m->ks.value) && m->ks.texture < 0);
        CHECK_STR_CONTAINS(m->description, "M: pbrt-v3 matte -> Lambert kd=0.5");
        CHECK(strstr(m->description, "sigma") == NULL);
    }
    /* Oren-Nayar sigma is ignored, with a note; an rgb Kd is taken as it is. */
    ps = make_params();
    add_rgb(&ps, "Kd", 0.1, 0.2, 0.3);
    add_float(&ps, "sigma", 20);
    i = build_keep(s, "matte", "Rough", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->kd.value.z, 0.3, 1e-6);
        CHECK(param_used(&ps, "Kd") && param_used(&ps, "sigma"));
        CHECK_STR_CONTAINS(m->description, "Rough: pbrt-v3 matte -> Lambert kd=(0.1, 0.2, 0.3)");
        CHECK_STR_CONTAINS(m->description, "Oren-Nayar sigma 20 ignored");
    }
    pn_params_free(&ps);
    /* A texture Kd is allowed. */
    ps = make_params();
    add_rgb(&ps, "value", 0.7, 0.6, 0.5);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_texture_from_pbrt(s, "konst", "spectrum", "constant", &ps, &err) == PN_OK);
    pn_params_free(&ps);
    ps = make_params();
    add_str(&ps, PN_PT_TEXTURE, "Kd", "konst");
    i = build_material(s, "matte", "Tex", &ps);
    if (i >= 0) {
        CHECK(s->materials[i].kd.texture == pn_scene_find_texture(s, "konst"));
        CHECK_STR_CONTAINS(s->materials[i].description, "kd=texture 'konst'");
    }
    /* Type errors are reported at the parameter. */
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Kd", "red");
    expect_param_error(s, "matte", &ps, "scene.pbrt:14:5:", "Kd");
    ps = make_params();
    add_rgb(&ps, "Kd", 0.5, 0.5, 0.5);
    add_bool(&ps, "sigma", true);
    expect_param_error(s, "matte", &ps, "scene.pbrt:15:5:", "sigma");
    free_scene(s);
}

static void test_v3_plastic(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "plastic", "P", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->kd.value.x, 0.25, 1e-6);
        CHECK_NEAR(m->ks.value.y, 0.25, 1e-6);
        /* Default roughness 0.1, remapped by pbrt-v3's quartic (not pbrt-v4's sqrt, which gives 18). */
        CHECK_NEAR(m->exponent, blinn_n(v3_alpha(0.1)), 1e-4);
        CHECK_NEAR(m->exponent, 7.37988, 1e-4);
        CHECK_STR_CONTAINS(m->description, "P: pbrt-v3 plastic -> Lambert kd=0.25 + Blinn ks=0.25 n=7.3799");
        CHECK_STR_CONTAINS(m->description, "(roughness 0.1, alpha 0.462)");
    }
    /* Roughness 0.5: alpha 1.13, so the exponent is clamped to 1. */
    ps = make_params();
    add_rgb(&ps, "Kd", 0.4, 0.3, 0.2);
    add_rgb(&ps, "Ks", 0.1, 0.1, 0.1);
    add_float(&ps, "roughness", 0.5);
    i = build_material(s, "plastic", "Soft", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->kd.value.y, 0.3, 1e-6);
        CHECK_NEAR(m->ks.value.x, 0.1, 1e-6);
        CHECK_NEAR(m->exponent, 1.0, 1e-6);
        CHECK_STR_CONTAINS(m->description, "alpha 1.13: n clamped to 1");
    }
    /* Without remapping alpha = roughness. */
    ps = make_params();
    add_float(&ps, "roughness", 0.1);
    add_bool(&ps, "remaproughness", false);
    i = build_material(s, "plastic", "Raw", &ps);
    if (i >= 0) CHECK_NEAR(s->materials[i].exponent, 2.0 / (0.1 * 0.1) - 2.0, 1e-3);
    /* plastic has no u/v roughness: they stay unused. */
    ps = make_params();
    add_float(&ps, "uroughness", 0.3);
    i = build_keep(s, "plastic", "UV", &ps);
    if (i >= 0) {
        CHECK(!param_used(&ps, "uroughness"));
        CHECK_NEAR(s->materials[i].exponent, blinn_n(v3_alpha(0.1)), 1e-4);
    }
    pn_params_free(&ps);
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Ks", "shiny");
    expect_param_error(s, "plastic", &ps, "scene.pbrt:14:5:", "Ks");
    free_scene(s);
}

static void test_v3_substrate(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "substrate", "S", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->kd.value.x, 0.5, 1e-6);
        CHECK_NEAR(m->ks.value.z, 0.5, 1e-6);
        CHECK_NEAR(m->exponent, blinn_n(v3_alpha(0.1)), 1e-4);
        CHECK_STR_CONTAINS(m->description, "S: pbrt-v3 substrate -> Lambert kd=0.5 + Blinn ks=0.5");
    }
    /* u and v are remapped separately and the alphas averaged; "roughness" is not a substrate input. */
    ps = make_params();
    add_rgb(&ps, "Kd", 0.6, 0.5, 0.4);
    add_rgb(&ps, "Ks", 0.04, 0.04, 0.04);
    add_float(&ps, "uroughness", 0.5);
    add_float(&ps, "vroughness", 0.1);
    add_float(&ps, "roughness", 0.9);
    i = build_keep(s, "substrate", "Aniso", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        double alpha = 0.5 * (v3_alpha(0.5) + v3_alpha(0.1));
        CHECK_NEAR(m->exponent, blinn_n(alpha), 1e-4);
        CHECK_NEAR(m->ks.value.y, 0.04, 1e-6);
        CHECK_NEAR(m->kd.value.x, 0.6, 1e-6);
        CHECK(!param_used(&ps, "roughness"));
    }
    pn_params_free(&ps);
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Kd", "brown");
    expect_param_error(s, "substrate", &ps, "scene.pbrt:14:5:", "Kd");
    free_scene(s);
}

static void test_v3_uber(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "uber", "U", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->kd.value.x, 0.25, 1e-6);
        CHECK_NEAR(m->ks.value.x, 0.25, 1e-6);
        CHECK_NEAR(m->exponent, blinn_n(v3_alpha(0.1)), 1e-4);
        CHECK_STR_CONTAINS(m->description, "U: pbrt-v3 uber -> Lambert kd=0.25 + Blinn ks=0.25");
        CHECK(s->warnings.count == 0);
    }
    /* Kr, Kt and opacity < 1 are dropped with warnings; a missing vroughness follows uroughness. */
    ps = make_params();
    add_rgb(&ps, "Kd", 0.3, 0.3, 0.3);
    add_rgb(&ps, "Kr", 0.2, 0.2, 0.2);
    add_rgb(&ps, "Kt", 0.1, 0.1, 0.1);
    add_rgb(&ps, "opacity", 0.5, 0.5, 0.5);
    add_float(&ps, "index", 1.33);
    add_float(&ps, "uroughness", 0.5);
    i = build_keep(s, "uber", "Busy", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->kd.value.x, 0.3, 1e-6);
        CHECK_NEAR(m->exponent, blinn_n(v3_alpha(0.5)), 1e-6);
        CHECK_NEAR(m->exponent, 1.0, 1e-6);
        CHECK(has_warning(s, "scene.pbrt:15:5:")); /* Kr */
        CHECK(has_warning(s, "specular reflection \"Kr\""));
        CHECK(has_warning(s, "specular transmission \"Kt\""));
        CHECK(has_warning(s, "\"opacity\" 0.5 (below 1) is ignored"));
        CHECK_STR_CONTAINS(m->description, "(Kr 0.2 dropped)");
        CHECK_STR_CONTAINS(m->description, "(eta 1.33 not used)");
        CHECK(param_used(&ps, "index") && param_used(&ps, "Kt") && param_used(&ps, "opacity"));
    }
    pn_params_free(&ps);
    /* "roughness" with u/v: u overrides, v falls back to u (not to roughness). */
    ps = make_params();
    add_float(&ps, "roughness", 0.01);
    add_float(&ps, "uroughness", 0.1);
    i = build_material(s, "uber", "UV", &ps);
    if (i >= 0) CHECK_NEAR(s->materials[i].exponent, blinn_n(v3_alpha(0.1)), 1e-4);
    ps = make_params();
    add_float(&ps, "roughness", 0.1);
    add_nums(&ps, PN_PT_BOOL, "opacity", 1, (const double[]){1.0});
    expect_param_error(s, "uber", &ps, "scene.pbrt:15:5:", "opacity");
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Kd", "grey");
    expect_param_error(s, "uber", &ps, "scene.pbrt:14:5:", "Kd");
    free_scene(s);
}

static void test_v3_glass(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "glass", "G", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_DIELECTRIC);
        CHECK_NEAR(m->eta, 1.5, 1e-6);
        CHECK_NEAR(m->specular.x, 1.0, 1e-6);
        CHECK_NEAR(m->specular.z, 1.0, 1e-6);
        CHECK_STR_CONTAINS(m->description, "G: pbrt-v3 glass -> dielectric eta=1.5");
        CHECK(s->warnings.count == 0);
    }
    /* "index" is pbrt-v3's older name for eta; "eta" wins when both are given. */
    ps = make_params();
    add_float(&ps, "index", 1.33);
    i = build_material(s, "glass", "Water", &ps);
    if (i >= 0) CHECK_NEAR(s->materials[i].eta, 1.33, 1e-6);
    ps = make_params();
    add_float(&ps, "eta", 1.6);
    add_float(&ps, "index", 1.33);
    i = build_keep(s, "glass", "Both", &ps);
    if (i >= 0) {
        CHECK_NEAR(s->materials[i].eta, 1.6, 1e-6);
        CHECK(!param_used(&ps, "index"));
    }
    pn_params_free(&ps);
    /* A non-white Kr tints the glass (and the description says so); a non-white Kt is dropped. */
    ps = make_params();
    add_rgb(&ps, "Kr", 0.9, 0.8, 0.7);
    add_rgb(&ps, "Kt", 0.5, 0.6, 0.7);
    i = build_material(s, "glass", "Tinted", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->specular.x, 0.9, 1e-6);
        CHECK_NEAR(m->specular.y, 0.8, 1e-6);
        CHECK_NEAR(m->specular.z, 0.7, 1e-6);
        CHECK_STR_CONTAINS(m->description, "specular tint Kr=(0.9, 0.8, 0.7)");
        CHECK_STR_CONTAINS(m->description, "Kt=(0.5, 0.6, 0.7) dropped");
        CHECK(has_warning(s, "transmission tint Kt"));
    }
    /* Kr = 0 (transmission only): the tint comes from Kt. Rough glass is rendered smooth. */
    ps = make_params();
    add_rgb(&ps, "Kr", 0, 0, 0);
    add_rgb(&ps, "Kt", 0.5, 0.6, 0.7);
    add_float(&ps, "uroughness", 0.1);
    i = build_material(s, "glass", "Clear", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->specular.x, 0.5, 1e-6);
        CHECK_NEAR(m->specular.z, 0.7, 1e-6);
        CHECK_STR_CONTAINS(m->description, "specular tint Kt=(0.5, 0.6, 0.7)");
        CHECK(has_warning(s, "rough glass"));
    }
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Kr", "white");
    expect_param_error(s, "glass", &ps, "scene.pbrt:14:5:", "Kr");
    ps = make_params();
    add_float(&ps, "index", -1.0);
    expect_param_error(s, "glass", &ps, "scene.pbrt:14:5:", "index");
    free_scene(s);
}

static void test_v3_metal(void) {
    struct pn_scene_s *s = new_scene();
    vec3 eta, k;
    CHECK(pn_named_spectrum_rgb("metal-Cu-eta", &eta));
    CHECK(pn_named_spectrum_rgb("metal-Cu-k", &k));
    /* Default: copper at roughness 0.01, which pbrt-v3 remaps to alpha 0.139 (a glossy lobe). */
    pn_params ps = make_params();
    int i = build_material(s, "metal", "Cu", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK(v3_is_zero(m->kd.value));
        CHECK_NEAR(m->ks.value.x, f0_conductor(eta.x, k.x), 1e-5);
        CHECK_NEAR(m->ks.value.z, f0_conductor(eta.z, k.z), 1e-5);
        CHECK_NEAR(m->exponent, blinn_n(v3_alpha(0.01)), 1e-3);
        CHECK_STR_CONTAINS(m->description, "Cu: pbrt-v3 metal -> Blinn ks=");
        CHECK_STR_CONTAINS(m->description, "copper (default)");
    }
    /* Unremapped roughness 0: a mirror with the metal's F0. */
    ps = make_params();
    add_rgb(&ps, "eta", 0.2, 0.9, 1.1);
    add_rgb(&ps, "k", 3.9, 2.4, 2.2);
    add_float(&ps, "roughness", 0.0);
    add_bool(&ps, "remaproughness", false);
    i = build_material(s, "metal", "Smooth", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_MIRROR);
        CHECK_NEAR(m->specular.x, f0_conductor(0.2, 3.9), 1e-5);
        CHECK_NEAR(m->specular.y, f0_conductor(0.9, 2.4), 1e-5);
        CHECK_NEAR(m->specular.z, f0_conductor(1.1, 2.2), 1e-5);
        CHECK_STR_CONTAINS(m->description, "Smooth: pbrt-v3 metal -> mirror");
    }
    /* u/v roughness remapped separately (v falls back to "roughness"); "reflectance" is not a
     * pbrt-v3 metal input and stays unused. */
    ps = make_params();
    add_float(&ps, "roughness", 0.5);
    add_float(&ps, "uroughness", 0.1);
    add_rgb(&ps, "reflectance", 0.9, 0.9, 0.9);
    i = build_keep(s, "metal", "Brushed", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK_NEAR(m->exponent, blinn_n(0.5 * (v3_alpha(0.1) + v3_alpha(0.5))), 1e-4);
        CHECK_NEAR(m->ks.value.x, f0_conductor(eta.x, k.x), 1e-5);
        CHECK(!param_used(&ps, "reflectance"));
    }
    pn_params_free(&ps);
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "k", "metal-Cu-k");
    expect_param_error(s, "metal", &ps, "scene.pbrt:14:5:", "k");
    free_scene(s);
}

static void test_v3_mirror(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    int i = build_material(s, "mirror", "Mi", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_MIRROR);
        CHECK_NEAR(m->specular.x, 0.9, 1e-6);
        CHECK_NEAR(m->specular.z, 0.9, 1e-6);
        CHECK_STR_CONTAINS(m->description, "Mi: pbrt-v3 mirror -> mirror specular=0.9");
    }
    ps = make_params();
    add_rgb(&ps, "Kr", 0.8, 0.7, 0.6);
    i = build_material(s, "mirror", "Gold", &ps);
    if (i >= 0) {
        CHECK_NEAR(s->materials[i].specular.y, 0.7, 1e-6);
        CHECK_STR_CONTAINS(s->materials[i].description, "specular=(0.8, 0.7, 0.6)");
    }
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "Kr", "silver");
    expect_param_error(s, "mirror", &ps, "scene.pbrt:14:5:", "Kr");
    free_scene(s);
}

/* The unsupported pbrt-v3 types become diffuse stand-ins with a warning. */
static void check_v3_substitute(const char *type, const char *colour_param, double expect_kd) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    if (colour_param) add_rgb(&ps, colour_param, 0.2, 0.4, 0.6);
    add_float(&ps, "eta", 1.33); /* other inputs are accepted without "unused" warnings */
    add_str(&ps, PN_PT_STRING, "bsdffile", "x.bsdf");
    int i = build_keep(s, type, "Sub", &ps);
    if (i >= 0) {
        const pn_material *m = &s->materials[i];
        CHECK(m->kind == PN_MATERIAL_LAMBERT_BLINN);
        CHECK_NEAR(m->kd.value.x, colour_param ? 0.2 : expect_kd, 1e-6);
        CHECK_NEAR(m->kd.value.z, colour_param ? 0.6 : expect_kd, 1e-6);
        CHECK(v3_is_zero(m->ks.value));
        char want[96];
        snprintf(want, sizeof want, "Sub: pbrt-v3 %s -> Lambert kd=", type);
        CHECK_STR_CONTAINS(m->description, want);
        snprintf(want, sizeof want, "pbrt-v3 %s material is not supported", type);
        CHECK(has_warning(s, want));
        CHECK(param_used(&ps, "eta") && param_used(&ps, "bsdffile"));
    }
    pn_params_free(&ps);
    /* The colour is still read with the typed getter: a string is an error at its location. */
    ps = make_params();
    add_str(&ps, PN_PT_STRING, colour_param ? colour_param : "Kd", "green");
    expect_param_error(s, type, &ps, "scene.pbrt:14:5:", colour_param ? colour_param : "Kd");
    free_scene(s);
}

static void test_v3_translucent(void) {
    check_v3_substitute("translucent", "Kd", 0.5);
}
static void test_v3_kdsubsurface(void) {
    check_v3_substitute("kdsubsurface", NULL, 0.5);
}
static void test_v3_fourier(void) {
    check_v3_substitute("fourier", "reflectance", 0.5);
}
static void test_v3_disney(void) {
    check_v3_substitute("disney", "color", 0.5);
}

static void test_v3_mix(void) {
    struct pn_scene_s *s = new_scene();
    pn_params ps = make_params();
    build_material(s, "matte", "A", &ps);
    ps = make_params();
    build_material(s, "mirror", "B", &ps);
    /* pbrt-v3's amount weights the first material: a per-hit choice of A with probability 0.7
     * (set as the second input of the MIX record, whose amount is its probability). */
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "namedmaterial1", "A");
    add_str(&ps, PN_PT_STRING, "namedmaterial2", "B");
    add_float(&ps, "amount", 0.7);
    int i = build_material(s, "mix", "MixA", &ps);
    int ia = pn_scene_find_material(s, "A"), ib = pn_scene_find_material(s, "B");
    if (i >= 0) {
        CHECK(s->materials[i].kind == PN_MATERIAL_MIX);
        CHECK(s->materials[i].mix[1] == ia && s->materials[i].mix[0] == ib);
        CHECK_NEAR(s->materials[i].mix_amount.value.y, 0.7, 1e-6);
        CHECK_STR_CONTAINS(s->materials[i].description, "MixA: pbrt-v3 mix -> per-hit choice of 'B' and 'A'");
    }
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "namedmaterial1", "A");
    add_str(&ps, PN_PT_STRING, "namedmaterial2", "B");
    add_rgb(&ps, "amount", 0.3, 0.3, 0.3);
    i = build_material(s, "mix", "MixB", &ps);
    if (i >= 0) CHECK(s->materials[i].kind == PN_MATERIAL_MIX && s->materials[i].mix[1] == ia);
    /* amount 1 is A alone (a constant amount at 0 or 1 is one material, as in pbrt). */
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "namedmaterial1", "A");
    add_str(&ps, PN_PT_STRING, "namedmaterial2", "B");
    add_float(&ps, "amount", 1.0);
    i = build_material(s, "mix", "MixC", &ps);
    if (i >= 0) CHECK(s->materials[i].kind == PN_MATERIAL_LAMBERT_BLINN);
    ps = make_params();
    add_str(&ps, PN_PT_STRING, "namedmaterial1", "A");
    add_str(&ps, PN_PT_STRING, "namedmaterial2", "Nope");
    expect_param_error(s, "mix", &ps, "scene.pbrt:15:5:", "Nope");
    free_scene(s);
}

/* ---- spectra ------------------------------------------------------------------------------- */

static void test_spectra(void) {
    vec3 c = pn_blackbody_rgb(6500.0);
    CHECK_NEAR(v3_luminance(c), 1.0, 2e-3);
    CHECK_NEAR(c.x, 1.0, 0.1);
    CHECK_NEAR(c.y, 1.0, 0.1);
    CHECK_NEAR(c.z, 1.0, 0.1);
    vec3 warm = pn_blackbody_rgb(2700.0);
    CHECK(warm.x > warm.y && warm.y > warm.z);
    CHECK_NEAR(v3_luminance(warm), 1.0, 2e-3);

    pn_params ps = make_params();
    double bb = 6500.0;
    add_nums(&ps, PN_PT_BLACKBODY, "L", 1, &bb);
    double konst[6] = {380, 0.3, 500, 0.3, 780, 0.3};
    add_nums(&ps, PN_PT_SPECTRUM, "refl", 6, konst);
    double big[4] = {300, 2.5, 900, 2.5};
    add_nums(&ps, PN_PT_SPECTRUM, "eta", 4, big);
    add_str(&ps, PN_PT_SPECTRUM, "named", "metal-Au-k");
    add_str(&ps, PN_PT_SPECTRUM, "illum", "stdillum-D65");
    add_str(&ps, PN_PT_SPECTRUM, "bogus", "metal-Xx-eta");
    add_rgb(&ps, "wrong", 1, 2, 3);
    ps.items[ps.count - 1].num_count = 2;
    pn_err err;
    pn_err_init(&err);
    vec3 out;
    bool found = false;
    CHECK(pn_params_rgb(&ps, "L", v3(0, 0, 0), PN_SPECTRUM_ILLUMINANT, &out, &found, &err) == PN_OK);
    CHECK(found);
    CHECK_NEAR(v3_luminance(out), 1.0, 2e-3);
    CHECK(pn_params_rgb(&ps, "refl", v3(0, 0, 0), PN_SPECTRUM_ALBEDO, &out, NULL, &err) == PN_OK);
    CHECK_NEAR(out.x, 0.3, 1e-3);
    CHECK_NEAR(out.y, 0.3, 1e-3);
    CHECK_NEAR(out.z, 0.3, 1e-3);
    CHECK(pn_params_rgb(&ps, "eta", v3(0, 0, 0), PN_SPECTRUM_UNBOUNDED, &out, NULL, &err) == PN_OK);
    CHECK_NEAR(out.x, 2.5, 1e-3);
    CHECK_NEAR(out.z, 2.5, 1e-3);
    CHECK(pn_params_rgb(&ps, "named", v3(0, 0, 0), PN_SPECTRUM_UNBOUNDED, &out, NULL, &err) == PN_OK);
    CHECK(out.x > out.z);
    CHECK(pn_params_rgb(&ps, "illum", v3(0, 0, 0), PN_SPECTRUM_ILLUMINANT, &out, NULL, &err) == PN_OK);
    CHECK_NEAR(out.y, 1.0, 1e-6);
    CHECK(pn_params_rgb(&ps, "absent", v3(0.1f, 0.2f, 0.3f), PN_SPECTRUM_ALBEDO, &out, &found, &err) == PN_OK);
    CHECK(!found);
    CHECK_NEAR(out.y, 0.2, 1e-6);
    CHECK(pn_params_rgb(&ps, "bogus", v3(0, 0, 0), PN_SPECTRUM_UNBOUNDED, &out, NULL, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "unknown named spectrum");
    pn_err_init(&err);
    CHECK(pn_params_rgb(&ps, "wrong", v3(0, 0, 0), PN_SPECTRUM_ALBEDO, &out, NULL, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:");
    pn_params_free(&ps);
}

static void test_spd_file(void) {
    char dir[] = "/tmp/pn_test_materials_XXXXXX";
    if (!mkdtemp(dir)) {
        pn_test_skip("no temporary folder");
        return;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/flat.spd", dir);
    FILE *f = fopen(path, "w");
    fprintf(f, "# a flat spectrum\n350 0.25\n550 0.25 # middle\n850 0.25\n");
    fclose(f);
    pn_params ps = make_params();
    ps.base_dir = dir;
    add_str(&ps, PN_PT_SPECTRUM, "k", "flat.spd");
    add_str(&ps, PN_PT_SPECTRUM, "missing", "nothere.spd");
    pn_err err;
    pn_err_init(&err);
    vec3 out;
    CHECK(pn_params_rgb(&ps, "k", v3(0, 0, 0), PN_SPECTRUM_UNBOUNDED, &out, NULL, &err) == PN_OK);
    CHECK_NEAR(out.x, 0.25, 1e-3);
    CHECK_NEAR(out.y, 0.25, 1e-3);
    CHECK(pn_params_rgb(&ps, "missing", v3(0, 0, 0), PN_SPECTRUM_UNBOUNDED, &out, NULL, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:15:5:");
    CHECK_STR_CONTAINS(err.message, "nothere.spd");
    pn_params_free(&ps);
    unlink(path);
    rmdir(dir);
}

/* ---- lights --------------------------------------------------------------------------------- */

static void test_light_power(void) {
    struct pn_scene_s *s = new_scene();
    mat4 m = mat4_translate(1, 2, 3);
    pn_err err;
    pn_err_init(&err);

    pn_params ps = make_params();
    add_rgb(&ps, "I", 1, 2, 3);
    add_float(&ps, "power", 100);
    add_float(&ps, "scale", 2);
    CHECK(pn_light_from_pbrt(s, "point", &ps, &m, &err) == PN_OK);
    pn_params_free(&ps);
    if (s->light_def_count == 1) {
        const pn_light_def *d = &s->light_defs[0];
        CHECK(d->kind == PN_LIGHTDEF_POINT);
        /* pbrt-v4 SpectrumToPhotometric ignores the magnitude of an rgb I: I * scale * P / 4 pi. */
        CHECK_NEAR(d->intensity.y, 2.0 * 2.0 * 100.0 / (4.0 * M_PI), 1e-4);
        CHECK_NEAR(d->position.x, 1.0, 1e-6);
        CHECK_NEAR(d->position.z, 3.0, 1e-6);
        CHECK_STR_CONTAINS(d->source, "scene.pbrt:12");
    }

    ps = make_params();
    add_float(&ps, "power", 50);
    add_float(&ps, "coneangle", 40);
    add_float(&ps, "conedeltaangle", 10);
    double from[3] = {0, 0, 0}, to[3] = {0, 1, 0};
    add_nums(&ps, PN_PT_POINT3, "from", 3, from);
    add_nums(&ps, PN_PT_POINT3, "to", 3, to);
    CHECK(pn_light_from_pbrt(s, "spot", &ps, &m, &err) == PN_OK);
    pn_params_free(&ps);
    if (s->light_def_count == 2) {
        const pn_light_def *d = &s->light_defs[1];
        double c_end = cos(40.0 * M_PI / 180.0), c_start = cos(30.0 * M_PI / 180.0);
        CHECK(d->kind == PN_LIGHTDEF_SPOT);
        CHECK_NEAR(d->cos_total_width, c_end, 1e-6);
        CHECK_NEAR(d->cos_falloff_start, c_start, 1e-6);
        double k_e = 2.0 * M_PI * ((1.0 - c_start) + (c_start - c_end) / 2.0);
        CHECK_NEAR(d->intensity.x, 50.0 / k_e, 1e-3);
        CHECK_NEAR(d->direction.y, 1.0, 1e-6);
        CHECK_NEAR(d->position.y, 2.0, 1e-6);
    }

    ps = make_params();
    add_rgb(&ps, "L", 3, 3, 3);
    CHECK(pn_light_from_pbrt(s, "distant", &ps, &m, &err) == PN_OK);
    pn_params_free(&ps);
    if (s->light_def_count == 3) {
        CHECK_NEAR(s->light_defs[2].direction.z, -1.0, 1e-6); /* from - to = (0,0,-1) */
        CHECK_NEAR(s->light_defs[2].intensity.x, 3.0, 1e-6);
    }

    ps = make_params();
    /* Supported now; without its required "filename" it is bad input at the directive. */
    CHECK(pn_light_from_pbrt(s, "projection", &ps, &m, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:12:3:");
    CHECK_STR_CONTAINS(err.message, "\"filename\"");
    pn_params_free(&ps);

    /* Area light: radiance = L * scale, then power / (pi * sides * area) (an rgb L counts by its
     * illuminant only, as pbrt-v4's SpectrumToPhotometric). */
    ps = make_params();
    add_rgb(&ps, "L", 2, 2, 2);
    add_float(&ps, "scale", 3);
    add_float(&ps, "power", 100);
    pn_area_light_desc desc;
    pn_err_init(&err);
    CHECK(pn_area_light_from_pbrt(s, "diffuse", &ps, &desc, &err) == PN_OK);
    pn_params_free(&ps);
    CHECK_NEAR(desc.emission.radiance.x, 6.0, 1e-6);
    CHECK_NEAR(desc.power, 100.0, 1e-9);
    pn_area_light_apply_power(&desc, 2.0, "sphere");
    CHECK_NEAR(desc.emission.radiance.x, 6.0 * 100.0 / (M_PI * 2.0), 1e-3);
    ps = make_params();
    pn_err_init(&err);
    CHECK(pn_area_light_from_pbrt(s, "goniometric", &ps, &desc, &err) == PN_ERROR_BAD_INPUT);
    pn_params_free(&ps);
    free_scene(s);
}

/* ---- textures ------------------------------------------------------------------------------- */

/* A 2 x 2 image: top row (0, 0.2, 0.4) (1, 1, 1); bottom row (0.5, 0.5, 0.5) (0.3, 0.6, 0.9). */
static bool write_test_image(const char *path) {
    pn_image img = pn_image_create(2, 2);
    if (!img) return false;
    const float px[12] = {0, 0.2f, 0.4f, 1, 1, 1, 0.5f, 0.5f, 0.5f, 0.3f, 0.6f, 0.9f};
    memcpy(img->layers[0].data, px, sizeof px);
    pn_err err;
    pn_err_init(&err);
    bool ok = pn_image_write_file(img, path, 0.0f, &err) == PN_OK;
    pn_image_free(img);
    return ok;
}

static void test_texture_eval(void) {
    char dir[] = "/tmp/pn_test_materials_XXXXXX";
    if (!mkdtemp(dir)) {
        pn_test_skip("no temporary folder");
        return;
    }
    char path[256];
    snprintf(path, sizeof path, "%s/tiny.pfm", dir);
    if (!write_test_image(path)) {
        pn_test_skip("cannot write a PFM image");
        rmdir(dir);
        return;
    }
    struct pn_scene_s *s = new_scene();
    pn_err err;
    pn_err_init(&err);
    const char *wraps[3] = {"repeat", "clamp", "black"};
    for (int w = 0; w < 3; w++) {
        pn_params ps = make_params();
        ps.base_dir = dir;
        add_str(&ps, PN_PT_STRING, "filename", "tiny.pfm");
        add_str(&ps, PN_PT_STRING, "wrap", wraps[w]);
        add_str(&ps, PN_PT_STRING, "filter", "trilinear");
        char name[16];
        snprintf(name, sizeof name, "t%d", w);
        CHECK_MSG(pn_texture_from_pbrt(s, name, "spectrum", "imagemap", &ps, &err) == PN_OK, "%s", err.message);
        pn_params_free(&ps);
    }
    CHECK(s->texture_count == 3);
    CHECK(s->image_count == 1); /* the same file is decoded once */
    if (s->texture_count == 3) {
        pn_texref r = {0, {0, 0, 0}};
        /* u = 0.25, v = 0.75 -> (s, 1 - t) = (0.25, 0.25): exactly the top-left texel centre. */
        vec3 c = pn_texture_eval(s, r, 0.25f, 0.75f);
        CHECK_NEAR(c.x, 0.0, 1e-6);
        CHECK_NEAR(c.y, 0.2, 1e-6);
        /* Centre of the image: the average of the four texels. */
        c = pn_texture_eval(s, r, 0.5f, 0.5f);
        CHECK_NEAR(c.x, (0 + 1 + 0.5 + 0.3) / 4.0, 1e-6);
        CHECK_NEAR(c.z, (0.4 + 1 + 0.5 + 0.9) / 4.0, 1e-6);
        /* u = 0.375 (x = 0.25), v = 0.25 (bottom-row centre): 3/4 of (0.5) + 1/4 of (0.3) in red. */
        c = pn_texture_eval(s, r, 0.375f, 0.25f);
        CHECK_NEAR(c.x, 0.75 * 0.5 + 0.25 * 0.3, 1e-6);
        /* u = 0 on the top row: repeat blends the left and right columns, clamp keeps the left,
         * black halves it. */
        vec3 rep = pn_texture_eval(s, (pn_texref){0, {0, 0, 0}}, 0.0f, 0.75f);
        vec3 clm = pn_texture_eval(s, (pn_texref){1, {0, 0, 0}}, 0.0f, 0.75f);
        vec3 blk = pn_texture_eval(s, (pn_texref){2, {0, 0, 0}}, 0.0f, 0.75f);
        CHECK_NEAR(rep.y, 0.5 * (0.2 + 1.0), 1e-6);
        CHECK_NEAR(clm.y, 0.2, 1e-6);
        CHECK_NEAR(blk.y, 0.1, 1e-6);
    }
    /* A float texture of the same file averages the channels; a scale texture halves it. */
    pn_params ps = make_params();
    ps.base_dir = dir;
    add_str(&ps, PN_PT_STRING, "filename", "tiny.pfm");
    add_float(&ps, "uscale", 2.0);
    CHECK(pn_texture_from_pbrt(s, "t0", "float", "imagemap", &ps, &err) == PN_OK);
    pn_params_free(&ps);
    ps = make_params();
    add_str(&ps, PN_PT_TEXTURE, "tex", "t0");
    add_float(&ps, "scale", 0.5);
    CHECK(pn_texture_from_pbrt(s, "half", "spectrum", "scale", &ps, &err) == PN_OK);
    pn_params_free(&ps);
    CHECK(s->image_count == 1);
    int ft = pn_scene_find_texture_typed(s, "t0", true);
    int half = pn_scene_find_texture(s, "half");
    CHECK(ft == 3 && half == 4);
    if (ft == 3 && half == 4) {
        /* uscale 2: u = 0.125 -> s = 0.25 */
        vec3 c = pn_texture_eval(s, (pn_texref){ft, {0, 0, 0}}, 0.125f, 0.75f);
        CHECK_NEAR(c.x, 0.2, 1e-6);
        CHECK_NEAR(c.z, 0.2, 1e-6);
        c = pn_texture_eval(s, (pn_texref){half, {0, 0, 0}}, 0.25f, 0.75f);
        CHECK_NEAR(c.y, 0.1, 1e-6);
        /* A material input naming the spectrum texture "t0" finds it, not the float one. */
        ps = make_params();
        add_str(&ps, PN_PT_TEXTURE, "reflectance", "t0");
        int mi = build_material(s, "diffuse", "Tex", &ps);
        if (mi >= 0) {
            CHECK(s->materials[mi].kd.texture == 0);
            CHECK_STR_CONTAINS(s->materials[mi].description, "kd=texture 't0'");
        }
    }
    /* diffusetransmission's "scale" on a textured reflectance becomes a scale texture. */
    ps = make_params();
    add_str(&ps, PN_PT_TEXTURE, "reflectance", "t0");
    add_float(&ps, "scale", 0.5);
    int dt = build_material(s, "diffusetransmission", "Leaves", &ps);
    if (dt >= 0) {
        pn_texref kd = s->materials[dt].kd;
        CHECK(kd.texture >= 0 && s->textures[kd.texture].kind == PN_TEXTURE_SCALE);
        CHECK_NEAR(pn_texture_eval(s, kd, 0.25f, 0.75f).y, 0.1, 1e-6);
        CHECK_STR_CONTAINS(s->materials[dt].description, "texture 't0 x 0.5'");
    }
    /* A checkerboard: tex1 where floor(s) + floor(t) is even. */
    ps = make_params();
    add_float(&ps, "tex1", 0.25);
    add_float(&ps, "tex2", 0.75);
    add_float(&ps, "uscale", 4);
    add_float(&ps, "vscale", 4);
    CHECK(pn_texture_from_pbrt(s, "check", "float", "checkerboard", &ps, &err) == PN_OK);
    pn_params_free(&ps);
    int ck = pn_scene_find_texture(s, "check");
    if (ck >= 0) {
        CHECK_NEAR(pn_texture_eval(s, (pn_texref){ck, {0, 0, 0}}, 0.1f, 0.1f).x, 0.25, 1e-6);
        CHECK_NEAR(pn_texture_eval(s, (pn_texref){ck, {0, 0, 0}}, 0.3f, 0.1f).x, 0.75, 1e-6);
        CHECK_NEAR(pn_texture_eval(s, (pn_texref){ck, {0, 0, 0}}, 0.3f, 0.3f).x, 0.25, 1e-6);
    }
    /* A missing image is an error at the filename parameter, with the reader's message. */
    ps = make_params();
    ps.base_dir = dir;
    add_str(&ps, PN_PT_STRING, "filename", "missing.png");
    pn_err_init(&err);
    CHECK(pn_texture_from_pbrt(s, "bad", "spectrum", "imagemap", &ps, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:14:5:");
    CHECK_STR_CONTAINS(err.message, "missing.png");
    pn_params_free(&ps);
    /* An unknown class is an error at the directive. */
    ps = make_params();
    pn_err_init(&err);
    CHECK(pn_texture_from_pbrt(s, "x", "float", "nosuch", &ps, &err) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "scene.pbrt:12:3: unknown texture class");
    pn_params_free(&ps);

    /* An infinite light with a square image: equal-area, sharing the image table. */
    ps = make_params();
    ps.base_dir = dir;
    add_str(&ps, PN_PT_STRING, "filename", "tiny.pfm");
    add_float(&ps, "scale", 2);
    mat4 id = mat4_identity();
    pn_err_init(&err);
    CHECK_MSG(pn_light_from_pbrt(s, "infinite", &ps, &id, &err) == PN_OK, "%s", err.message);
    pn_params_free(&ps);
    if (s->light_def_count == 1) {
        CHECK(s->light_defs[0].equal_area);
        CHECK(s->light_defs[0].image == 0);
        CHECK_NEAR(s->light_defs[0].intensity.y, 2.0, 1e-6);
    }
    /* "illuminance" of a constant white equal-area environment: the cosine-weighted upper
     * hemisphere of radiance 1 gives pi, but pbrt-v4 weights each texel by 2 pi / (w h), half
     * its solid angle, so its estimate is pi / 2 and scale = 2 E / pi (up to the texel
     * discretisation). */
    char white[256];
    snprintf(white, sizeof white, "%s/white.pfm", dir);
    pn_image wimg = pn_image_create(32, 32);
    bool wrote = false;
    if (wimg) {
        for (int i = 0; i < 3 * 32 * 32; i++) wimg->layers[0].data[i] = 1.0f;
        pn_err_init(&err);
        wrote = pn_image_write_file(wimg, white, 0.0f, &err) == PN_OK;
        pn_image_free(wimg);
    }
    CHECK(wrote);
    if (wrote) {
        ps = make_params();
        ps.base_dir = dir;
        add_str(&ps, PN_PT_STRING, "filename", "white.pfm");
        add_float(&ps, "illuminance", 10.0);
        pn_err_init(&err);
        CHECK_MSG(pn_light_from_pbrt(s, "infinite", &ps, &id, &err) == PN_OK, "%s", err.message);
        pn_params_free(&ps);
        if (s->light_def_count == 2) CHECK_NEAR(s->light_defs[1].intensity.x, 20.0 / M_PI, 0.02 * 20.0 / M_PI);
        unlink(white);
    }
    ps = make_params();
    add_rgb(&ps, "L", 2, 2, 2);
    add_float(&ps, "illuminance", 10.0);
    CHECK(pn_light_from_pbrt(s, "infinite", &ps, &id, &err) == PN_OK);
    pn_params_free(&ps);
    if (s->light_def_count == 3) {
        CHECK(s->light_defs[2].image < 0);
        /* L * E / pi: the magnitude of an rgb L is kept (pbrt-v4 SpectrumToPhotometric). */
        CHECK_NEAR(s->light_defs[2].intensity.y, 2.0 * 10.0 / M_PI, 1e-4);
    }
    free_scene(s);
    unlink(path);
    rmdir(dir);
}

PN_TESTS(TEST(test_diffuse_default), TEST(test_coateddiffuse), TEST(test_conductor),
         TEST(test_dielectric_mix_interface), TEST(test_unknown_material), TEST(test_v3_remap_closed_form),
         TEST(test_v3_matte), TEST(test_v3_plastic), TEST(test_v3_substrate), TEST(test_v3_uber), TEST(test_v3_glass),
         TEST(test_v3_metal), TEST(test_v3_mirror), TEST(test_v3_translucent), TEST(test_v3_kdsubsurface),
         TEST(test_v3_fourier), TEST(test_v3_disney), TEST(test_v3_mix), TEST(test_spectra), TEST(test_spd_file),
         TEST(test_light_power), TEST(test_texture_eval))
