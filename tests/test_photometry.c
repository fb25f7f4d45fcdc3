/* test_photometry.c — measured luminaires (scene/photometry.c, lights/photometric.c): lumens of
 * known distributions against their closed forms and against a brute-force integral of the
 * lookup; the illuminance a luminaire gives a plane against I(theta, C) cos theta / d^2 with
 * I interpolated here by hand; a rendered plane against rho E / pi (the units convention,
 * docs/units.md); the symmetry forms of one distribution (single angle, 0-90, 0-180, 90-270,
 * 0-360 and EULUMDAT Isym 0-4) give identical lookups and renders; IES and EULUMDAT versions of
 * one luminaire agree; a chi-square test of the emission sampling with the unbiasedness of its
 * weights; type B, tilt and the lumen override; every integrator renders one; and every
 * malformed file is refused with file:line and its message (the CLI exits 3). */
#include "harness.h"

#include "lights/cluster_tree.h"
#include "lights/light_bvh.h"
#include "lights/lights.h"
#include "lights/vpl.h"
#include "penumbra/penumbra.h"
#include "scene/photometry.h"
#include "scene/scene.h"

#include <stdint.h>
#include <sys/wait.h>

#define PN_SCENE_FILES_PREFIX "pn_test_photometry"
#include "scene_files.h"
#include "stats_checks.h"

#define PI_D 3.14159265358979323846
#define DATA PN_SOURCE_DIR "/tests/data/photometry/"

/* A deterministic uniform number in [0, 1) (PCG's LCG step, top 53 bits). */
static double rnd(uint64_t *s) {
    *s = *s * 6364136223846793005ull + 1442695040888963407ull;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static pn_photometry *read_data(const char *name) {
    pn_err err;
    pn_err_init(&err);
    pn_photometry *p = NULL;
    char path[512];
    snprintf(path, sizeof path, DATA "%s", name);
    if (pn_photometry_read(path, path, &p, &err) != PN_OK) fprintf(stderr, "  %s\n", err.message);
    return p;
}

static vec3 dir_c(double gamma_deg, double c_deg) {
    double g = gamma_deg * PI_D / 180.0, c = c_deg * PI_D / 180.0;
    return v3((float)(sin(g) * cos(c)), (float)(sin(g) * sin(c)), (float)(-cos(g)));
}

/* Midpoint rule over (gamma, C) in 0.1 x 0.5 degree cells: an integral independent of the
 * cell-by-cell closed form of the reader. */
static double brute_lumens(const pn_photometry *p) {
    const int ng = 1800, nc = 720;
    double sum = 0.0;
    for (int j = 0; j < ng; j++) {
        double g = (j + 0.5) * 180.0 / ng;
        double w = sin(g * PI_D / 180.0) * (PI_D / ng) * (2.0 * PI_D / nc);
        for (int i = 0; i < nc; i++) sum += pn_photometry_eval(p, dir_c(g, (i + 0.5) * 360.0 / nc)) * w;
    }
    return sum;
}

/* ---- the distributions written in tests/data/photometry (the generator's formulas) ---------- */

static double street_cd(double g, double c) {
    if (g >= 90.0) return 0.0;
    double a = g * PI_D / 180.0;
    double v =
        60.0 + 240.0 * pow(sin(a), 2.0) * (1.0 + cos(c * PI_D / 180.0)) / 2.0 * pow(cos(a), 0.5) + 120.0 * cos(a);
    return round(v * 1000.0) / 1000.0; /* the file holds three decimals */
}

/* Bilinear interpolation of street_cd's table (gamma every 5, C every 15 degrees, mirrored
 * about the 0-180 plane), written out here. */
static double street_interp(double g, double c) {
    c = fmod(c, 360.0);
    if (c < 0.0) c += 360.0;
    if (c > 180.0) c = 360.0 - c;
    int j = (int)(g / 5.0), i = (int)(c / 15.0);
    if (j >= 36) j = 35;
    if (i >= 12) i = 11;
    double tg = (g - 5.0 * j) / 5.0, tc = (c - 15.0 * i) / 15.0;
    double a = street_cd(5.0 * j, 15.0 * i) * (1 - tg) + street_cd(5.0 * (j + 1), 15.0 * i) * tg;
    double b = street_cd(5.0 * j, 15.0 * (i + 1)) * (1 - tg) + street_cd(5.0 * (j + 1), 15.0 * (i + 1)) * tg;
    return a * (1 - tc) + b * tc;
}

/* ---- lumens ------------------------------------------------------------------------------------- */

static void test_lumens_match_stated(void) {
    struct {
        const char *file;
        double stated, exact;
    } cases[] = {
        {"isotropic.ies", 1000.0, 4.0 * PI_D * 79.5775}, /* the file's 6 digits of 1000 / 4 pi */
        {"cosine.ies", 1000.0, 1000.0},                  /* I0 cos: pi I0; the table's chords */
        {"isotropic.ldt", 2000.0, 2000.0 * 4.0 * PI_D * 79.5775 / 1000.0},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        pn_photometry *p = read_data(cases[k].file);
        CHECK(p != NULL);
        if (!p) continue;
        CHECK_NEAR(p->stated_lumens, cases[k].stated, 1e-9);
        CHECK_MSG(fabs(p->lumens / cases[k].stated - 1.0) < 0.01, "%s: %g lm, stated %g", cases[k].file, p->lumens,
                  cases[k].stated);
        CHECK_MSG(fabs(p->lumens / cases[k].exact - 1.0) < 2e-3, "%s: %g lm, closed form %g", cases[k].file, p->lumens,
                  cases[k].exact);
        pn_photometry_free(p);
    }
    /* The reader's cell-by-cell integral is the integral of its own lookup, for every form. */
    const char *files[] = {"street.ies",     "street.ldt",     "beam.ies",       "quad_90_270.ies",
                           "quad_isym3.ldt", "rot_single.ies", "flood_typeb.ies"};
    for (size_t k = 0; k < sizeof files / sizeof files[0]; k++) {
        pn_photometry *p = read_data(files[k]);
        CHECK(p != NULL);
        if (!p) continue;
        double b = brute_lumens(p);
        CHECK_MSG(fabs(p->lumens / b - 1.0) < 2e-3, "%s: closed form %g lm, brute force %g", files[k], p->lumens, b);
        pn_photometry_free(p);
    }
    /* The narrow beam in closed form: 5000 cd to 10 degrees, a linear ramp to 0 at 15. */
    pn_photometry *p = read_data("beam.ies");
    if (p) {
        double a10 = 10.0 * PI_D / 180.0, a15 = 15.0 * PI_D / 180.0, k = 5000.0 / (a15 - a10);
        /* int_a10^a15 k (a15 - g) sin g dg = k [(a15 - g)(-cos g) - sin g] */
        double ramp = k * ((0.0 - sin(a15)) - (-(a15 - a10) * cos(a10) - sin(a10)));
        double exact = 2.0 * PI_D * (5000.0 * (1.0 - cos(a10)) + ramp);
        CHECK_MSG(fabs(p->lumens / exact - 1.0) < 1e-9, "beam: %g lm, closed form %g", p->lumens, exact);
        CHECK(p->stated_lumens == -1.0); /* absolute photometry */
        pn_photometry_free(p);
    }
}

/* ---- symmetry forms and formats ------------------------------------------------------------------- */

static void check_same_lookup(const char *a, const char *b, double scale_b, double tol) {
    pn_photometry *p = read_data(a), *q = read_data(b);
    CHECK(p && q);
    if (p && q) {
        double worst = 0.0;
        uint64_t s = 12345;
        for (int k = 0; k < 20000; k++) {
            double g = rnd(&s) * 180.0, c = rnd(&s) * 360.0;
            vec3 w = dir_c(g, c);
            double x = pn_photometry_eval(p, w), y = pn_photometry_eval(q, w) * scale_b;
            worst = fmax(worst, fabs(x - y) / fmax(1.0, fabs(x)));
        }
        CHECK_MSG(worst <= tol, "%s vs %s: largest relative difference %g", a, b, worst);
        CHECK_MSG(fabs(p->lumens - q->lumens * scale_b) <= 1e-6 * p->lumens, "%s %g lm vs %s %g lm", a, p->lumens, b,
                  q->lumens * scale_b);
    }
    pn_photometry_free(p);
    pn_photometry_free(q);
}

static void test_symmetry_forms_agree(void) {
    const char *rot[] = {"rot_quadrant.ies", "rot_half.ies", "rot_90_270.ies", "rot_full.ies"};
    for (int k = 0; k < 4; k++) check_same_lookup("rot_single.ies", rot[k], 1.0, 1e-12);
    const char *quad[] = {"quad_half.ies",  "quad_90_270.ies", "quad_full.ies",
                          "quad_isym0.ldt", "quad_isym3.ldt",  "quad_isym4.ldt"};
    for (int k = 0; k < 6; k++) check_same_lookup("quad_quadrant.ies", quad[k], 1.0, 1e-9);
}

static bool render_ref(const char *name, const char *light, float *out, int res);

static void test_ies_and_eulumdat_agree(void) {
    check_same_lookup("street.ies", "street.ldt", 1.0, 1e-12);
    enum { R = 12 };
    static float a[3 * R * R], b[3 * R * R];
    bool ok = render_ref("ies.pbrt", "LightSource \"goniometric\" \"string filename\" \"" DATA "street.ies\"", a, R) &&
              render_ref("ldt.pbrt", "LightSource \"goniometric\" \"string filename\" \"" DATA "street.ldt\"", b, R);
    CHECK(ok);
    if (ok) CHECK_MSG(memcmp(a, b, sizeof a) == 0, "street.ies and street.ldt render differently");
    /* 2000 lm of lamps against 1000: the EULUMDAT intensities are per 1000 lm of lamp flux. */
    check_same_lookup("isotropic.ies", "isotropic.ldt", 0.5, 1e-12);
    pn_photometry *p = read_data("street.ldt");
    if (p) {
        CHECK_NEAR(p->stated_luminaire_lumens, 1000.0, 1e-9); /* LORL 100 % */
        pn_photometry_free(p);
    }
}

/* Type B: H rotates about +y from nadir towards +x, V leans towards +y (scene/photometry.h). */
static void test_type_b(void) {
    pn_photometry *p = read_data("flood_typeb.ies");
    CHECK(p != NULL);
    if (!p) return;
    double worst = 0.0;
    for (int h = -90; h <= 90; h += 15)
        for (int v = -90; v <= 90; v += 10) {
            double hr = h * PI_D / 180.0, vr = v * PI_D / 180.0;
            vec3 w = v3((float)(cos(vr) * sin(hr)), (float)sin(vr), (float)(-cos(vr) * cos(hr)));
            double want = 2000.0 * pow(cos(hr), 4.0) * pow(cos(vr), 2.0);
            worst = fmax(worst, fabs(pn_photometry_eval(p, w) - want) / fmax(1.0, want));
        }
    CHECK_MSG(worst < 1e-5, "type B nodes off by %g (relative; the file has 6 digits)", worst);
    CHECK(pn_photometry_eval(p, v3(0, 0, 1)) == 0.0); /* behind the floodlight: not measured */
    pn_photometry_free(p);
}

static void test_tilt_table(void) {
    pn_photometry *p = read_data("tilt.ies");
    CHECK(p != NULL);
    if (!p) return;
    CHECK(p->tilt_count == 3);
    CHECK_NEAR(pn_photometry_tilt_factor(p, 0.0), 1.0, 1e-12);
    CHECK_NEAR(pn_photometry_tilt_factor(p, 45.0), 0.9, 1e-12);
    CHECK_NEAR(pn_photometry_tilt_factor(p, 67.5), 0.85, 1e-12);
    CHECK_NEAR(pn_photometry_tilt_factor(p, 120.0), 0.8, 1e-12);
    pn_photometry_free(p);
}

/* Mutated and truncated copies of the good files (deterministic; a small in-test fuzz until the
 * fuzz targets exist): each parses or is refused with file:line, never crashes (run under ASan
 * by make sanitize), and what parses has finite, non-negative lumens. */
static void test_mutated_files_never_crash(void) {
    const char *files[] = {"street.ies", "street.ldt", "tilt.ies", "flood_typeb.ies", "quad_isym3.ldt"};
    uint64_t s = 7;
    int parsed = 0, refused = 0, bad = 0;
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        char path[512];
        snprintf(path, sizeof path, DATA "%s", files[f]);
        FILE *fp = fopen(path, "rb");
        if (!fp) continue;
        static char text[65536], copy[65536];
        size_t n = fread(text, 1, sizeof text, fp);
        fclose(fp);
        bool ldt = strstr(files[f], ".ldt") != NULL;
        for (int k = 0; k < 400; k++) {
            memcpy(copy, text, n);
            size_t len = n;
            for (int m = 0; m < 1 + k % 4; m++) {
                s = s * 6364136223846793005ull + 1442695040888963407ull;
                size_t at = (size_t)(s >> 33) % len;
                const char pool[] = "0123456789-.,e \n\r+nanINF[]";
                switch ((s >> 20) % 4) {
                case 0: copy[at] = pool[(s >> 8) % (sizeof pool - 1)]; break;
                case 1: len = at + 1; break; /* truncate */
                case 2: copy[at] = '\n'; break;
                default: copy[at] = (char)(s >> 40); break;
                }
            }
            pn_err err;
            pn_err_init(&err);
            pn_photometry *p = NULL;
            pn_status st = pn_photometry_parse(copy, len, "mutant", ldt, &p, &err);
            if (st == PN_OK) {
                parsed++;
                if (!(p && isfinite(p->lumens) && p->lumens >= 0.0 && p->peak_cd > 0.0)) bad++;
            } else {
                refused++;
                if (st != PN_ERROR_BAD_INPUT || strncmp(err.message, "mutant:", 7) != 0) bad++;
            }
            pn_photometry_free(p);
        }
    }
    fprintf(stderr, "  mutants: %d parsed, %d refused\n", parsed, refused);
    CHECK(bad == 0);
    CHECK(parsed > 0 && refused > 0);
}

/* ---- scenes --------------------------------------------------------------------------------------- */

static char scene_text[8192];

/* An orthographic camera 5 m above the plane z = 0 (kd 0.5, 8 m square) looking down at the
 * 2 m square under it; the luminaire `light` (a LightSource line) inside an attribute block with
 * `xform` (e.g. "Translate 0 0 2"). */
static const char *plane_scene(int res, const char *xform, const char *light) {
    snprintf(
        scene_text, sizeof scene_text,
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\"\n"
        "Film \"rgb\" \"integer xresolution\" [ %d ] \"integer yresolution\" [ %d ]\n"
        "PixelFilter \"box\"\nWorldBegin\nAttributeBegin\n%s\n%s\nAttributeEnd\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -4 -4 0  4 -4 0  4 4 0  -4 4 0 ] \"integer indices\" [ 0 1 2 0 2 3 ]\n",
        res, res, xform, light);
    return scene_text;
}

static pn_scene load_text(const char *name, const char *text) {
    write_file(name, text);
    pn_scene scene = NULL;
    if (pn_scene_load(test_context(), tpath(name), &scene) != PN_OK)
        fprintf(stderr, "  %s: %s\n", name, pn_context_error_message(test_context()));
    return scene;
}

static const pn_light *first_gonio(pn_scene scene) {
    const pn_lights *L = scene ? scene->lights : NULL;
    for (int i = 0; L && i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_GONIOMETRIC) return &L->lights[i];
    return NULL;
}

/* plane_scene with the luminaire `file` (in tests/data/photometry) under `xform`, and its light
 * record (NULL, with a failed check, when the scene does not load). */
static pn_scene load_luminaire(const char *name, const char *xform, const char *file, const pn_light **l) {
    char light[512];
    snprintf(light, sizeof light, "LightSource \"goniometric\" \"string filename\" \"" DATA "%s\"", file);
    pn_scene scene = load_text(name, plane_scene(4, xform, light));
    *l = first_gonio(scene);
    CHECK(*l != NULL);
    return scene;
}

/* E = I(theta, C) cos theta / d^2 on the plane, from the light's own sample (direct light
 * evaluation), against I interpolated here; the luminaire 2 m up, turned 30 degrees about z. */
static void test_illuminance_closed_form(void) {
    const pn_light *l = NULL;
    pn_scene scene = load_luminaire("street.pbrt", "Translate 0 0 2\nRotate 30 0 0 1", "street.ies", &l);
    if (!l) {
        pn_scene_free(scene);
        return;
    }
    double worst = 0.0;
    int lit = 0;
    for (int iy = -10; iy <= 10; iy++)
        for (int ix = -10; ix <= 10; ix++) {
            vec3 p = v3(0.37f * (float)ix, 0.41f * (float)iy, 0.0f);
            pn_light_sample s;
            bool ok = pn_light_sample_point(scene->lights, l, p, 0.5f, 0.5f, &s);
            double e = ok ? (double)v3_luminance(s.radiance) * (double)s.wi.z : 0.0;
            /* in the light's frame: undo the 30 degree turn */
            double dx = p.x, dy = p.y, dz = -2.0, d2 = dx * dx + dy * dy + dz * dz;
            double a = -30.0 * PI_D / 180.0;
            double lx = cos(a) * dx - sin(a) * dy, ly = sin(a) * dx + cos(a) * dy;
            double g = acos(-dz / sqrt(d2)) * 180.0 / PI_D, c = atan2(ly, lx) * 180.0 / PI_D;
            double want = street_interp(g, c) * (2.0 / sqrt(d2)) / d2;
            if (want > 0.0) lit++;
            worst = fmax(worst, fabs(e - want) / fmax(want, 1e-3));
        }
    CHECK(lit > 400);
    CHECK_MSG(worst < 0.005, "illuminance off by %.3g%% at worst", 100.0 * worst);
    /* the estimate the reference integrator's light PDF uses is the same exact value */
    double e_est = pn_light_irradiance_estimate(scene->lights, l, v3(0.5f, 0.2f, 0), v3(0, 0, 1));
    pn_light_sample s;
    pn_light_sample_point(scene->lights, l, v3(0.5f, 0.2f, 0), 0.5f, 0.5f, &s);
    CHECK_NEAR(e_est, (double)v3_luminance(s.radiance) * (double)s.wi.z, 1e-4 * e_est);
    pn_scene_free(scene);
}

/* The reference integrator's beauty layer of `scene` (2 threads, seed 3) into out (floats). */
static bool render_scene(pn_scene scene, int spp, float *out, size_t floats) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = PN_INTEGRATOR_REFERENCE;
    rs.spp = (uint32_t)spp;
    rs.threads = 2;
    rs.seed = 3;
    pn_image img = NULL;
    bool ok = scene && pn_render(test_context(), scene, &rs, &img, NULL) == PN_OK && img;
    if (ok) memcpy(out, pn_image_layer_data(img, 0), sizeof(float) * floats);
    pn_image_free(img);
    return ok;
}

/* A rendered pixel is luminance rho E / pi in cd/m^2 when the luminaire is in candela
 * (docs/units.md); here a Lambertian downlight I0 cos theta of 1000 lm, 2 m up: E = I0 h^2 /
 * d^4, and with "power" 500 and "scale" 2 it emits 1000 lm again. */
static void test_render_units(void) {
    const char *lights[2] = {"LightSource \"goniometric\" \"string filename\" \"" DATA "cosine.ies\"",
                             "LightSource \"goniometric\" \"string filename\" \"" DATA
                             "cosine.ies\" \"float power\" [ 500 ] \"float scale\" [ 2 ]"};
    for (int k = 0; k < 2; k++) {
        pn_scene scene = load_text("units.pbrt", plane_scene(16, "Translate 0 0 2", lights[k]));
        CHECK(scene != NULL);
        if (!scene) continue;
        const pn_light *l = first_gonio(scene);
        if (k == 1 && l) CHECK_NEAR(pn_gonio_photometric_power(scene->lights, l), 1000.0, 0.5);
        static float px[3 * 16 * 16];
        bool ok = render_scene(scene, 16, px, 3 * 16 * 16);
        CHECK(ok);
        if (ok) {
            pn_photometry *p = read_data("cosine.ies");
            double i0 = p ? p->cd[0] : 0.0, worst = 0.0;
            pn_photometry_free(p);
            for (int y = 0; y < 16; y++)
                for (int x = 0; x < 16; x++) {
                    /* pixel centres cover [-1, 1]^2; the distribution is round, so the camera's
                     * handedness does not matter */
                    double wx = -1.0 + (x + 0.5) / 8.0, wy = -1.0 + (y + 0.5) / 8.0;
                    double d2 = wx * wx + wy * wy + 4.0;
                    double cos_t = 2.0 / sqrt(d2), t = acos(cos_t) * 180.0 / PI_D;
                    /* the table's linear interpolation of cos between 2.5 degree nodes */
                    int j = (int)(t / 2.5);
                    double f = (t - 2.5 * j) / 2.5;
                    double ii = i0 * (cos(j * 2.5 * PI_D / 180.0) * (1 - f) + cos((j + 1) * 2.5 * PI_D / 180.0) * f);
                    double want = 0.5 / PI_D * ii * cos_t / d2;
                    const float *c = px + 3 * (y * 16 + x);
                    double got = 0.2126 * (double)c[0] + 0.7152 * (double)c[1] + 0.0722 * (double)c[2];
                    worst = fmax(worst, fabs(got / want - 1.0));
                }
            CHECK_MSG(worst < 0.005, "case %d: pixel luminance off rho E / pi by %.3g%% at worst", k, 100.0 * worst);
        }
        pn_scene_free(scene);
    }
}

static bool render_ref(const char *name, const char *light, float *out, int res) {
    pn_scene scene = load_text(name, plane_scene(res, "Translate 0 0 1.5\nRotate 20 1 0 0", light));
    bool ok = render_scene(scene, 4, out, 3 * (size_t)res * (size_t)res);
    pn_scene_free(scene);
    return ok;
}

/* The symmetry forms render the same image (rotational forms bit for bit). */
static void test_symmetry_forms_render_identically(void) {
    enum { R = 12 };
    static float base[3 * R * R], img[3 * R * R];
    char light[512];
    const char *rot[] = {"rot_single.ies", "rot_quadrant.ies", "rot_half.ies", "rot_90_270.ies", "rot_full.ies"};
    for (int k = 0; k < 5; k++) {
        snprintf(light, sizeof light, "LightSource \"goniometric\" \"string filename\" \"" DATA "%s\"", rot[k]);
        bool ok = render_ref("sym.pbrt", light, k == 0 ? base : img, R);
        CHECK(ok);
        if (ok && k > 0) CHECK_MSG(memcmp(base, img, sizeof img) == 0, "%s renders differently", rot[k]);
    }
    const char *quad[] = {"quad_quadrant.ies", "quad_half.ies", "quad_90_270.ies", "quad_full.ies", "quad_isym3.ldt"};
    for (int k = 0; k < 5; k++) {
        snprintf(light, sizeof light, "LightSource \"goniometric\" \"string filename\" \"" DATA "%s\"", quad[k]);
        bool ok = render_ref("symq.pbrt", light, k == 0 ? base : img, R);
        CHECK(ok);
        if (!ok || k == 0) continue;
        double worst = 0.0;
        for (int i = 0; i < 3 * R * R; i++)
            worst = fmax(worst, fabs((double)img[i] - (double)base[i]) / fmax(1e-6, (double)base[i]));
        CHECK_MSG(worst < 1e-5, "%s differs by %g relative", quad[k], worst);
    }
}

/* ---- emission sampling ---------------------------------------------------------------------------- */

/* Directions from pn_gonio_sample_direction against the density pn_gonio_pdf reports, binned
 * 16 x 16 in (C, gamma) of the light (a luminaire turned about x, so world and light differ);
 * E[I / pdf] is the luminaire's lumens. */
static void test_emission_sampling(void) {
    const pn_light *l = NULL;
    pn_scene scene = load_luminaire("chi2.pbrt", "Translate 0 0 2\nRotate 40 1 0 0", "street.ies", &l);
    if (!l) {
        pn_scene_free(scene);
        return;
    }
    const pn_gonio *g = &scene->lights->gonios[l->env];
    enum { NB = 16, N = 200000 };
    static double obs[NB * NB], prob[NB * NB];
    memset(obs, 0, sizeof obs);
    /* the expected probability of each bin: the density at the centres of the 256 x 512
     * sampling cells (constant on each), times their solid angle */
    for (int j = 0; j < 512; j++) {
        double g0 = PI_D * j / 512.0, g1 = PI_D * (j + 1) / 512.0, solid = (cos(g0) - cos(g1)) * 2.0 * PI_D / 256.0;
        for (int i = 0; i < 256; i++) {
            vec3 wl = dir_c((j + 0.5) * 180.0 / 512.0, (i + 0.5) * 360.0 / 256.0);
            vec3 w = v3_normalize(mat4_apply_vector(&g->world_from_light, wl));
            prob[(j / 32) * NB + i / 16] += (double)pn_gonio_pdf(scene->lights, l, w) * solid;
        }
    }
    double psum = 0.0;
    for (int b = 0; b < NB * NB; b++) psum += prob[b];
    CHECK_NEAR(psum, 1.0, 2e-3);
    uint64_t s = 99;
    double flux = 0.0;
    int pdf_mismatch = 0;
    for (int k = 0; k < N; k++) {
        float u1 = (float)rnd(&s), u2 = (float)rnd(&s);
        u1 = u1 < 1.0f ? u1 : 0x1.fffffep-1f;
        u2 = u2 < 1.0f ? u2 : 0x1.fffffep-1f;
        vec3 w;
        float pdf;
        if (!pn_gonio_sample_direction(scene->lights, l, u1, u2, &w, &pdf)) continue;
        float back = pn_gonio_pdf(scene->lights, l, w);
        /* the same cell's density, but for directions that round into a neighbouring cell */
        if (fabs((double)back / (double)pdf - 1.0) > 1e-3) pdf_mismatch++;
        vec3 wl = v3_normalize(mat4_apply_vector(&g->light_from_world, w));
        double gam = acos(fmax(-1.0, fmin(1.0, -(double)wl.z))) * 180.0 / PI_D;
        double c = atan2((double)wl.y, (double)wl.x) * 180.0 / PI_D;
        if (c < 0.0) c += 360.0;
        int bj = (int)(gam / 180.0 * NB), bi = (int)(c / 360.0 * NB);
        bj = bj >= NB ? NB - 1 : bj;
        bi = bi >= NB ? NB - 1 : bi;
        obs[bj * NB + bi] += 1.0;
        flux += (double)v3_luminance(l->emit) * (double)pn_gonio_factor(scene->lights, l, w) / (double)pdf;
    }
    CHECK_MSG(pdf_mismatch < N / 1000, "%d of %d sampled densities differ from pn_gonio_pdf", pdf_mismatch, N);
    CHECK(pn_test_chi2_ok(obs, prob, NB * NB, N));
    pn_photometry *p = read_data("street.ies");
    if (p) {
        flux /= N;
        CHECK_MSG(fabs(flux / p->lumens - 1.0) < 0.01, "E[I / pdf] = %g lm, the luminaire %g lm", flux, p->lumens);
        pn_photometry_free(p);
    }
    pn_scene_free(scene);
}

/* VPL light paths from a luminaire: a Lambertian downlight of 1000 lm, 2 m above a 400 m floor of
 * kd 0.5, leaves first-bounce VPLs whose power sums to kd x 1000 lm (the floor misses the
 * directions beyond atan(100) of nadir, 1e-4 of the flux), within 5 standard errors. */
static void test_vpl_first_bounce(void) {
    pn_scene scene =
        load_text("vpl.pbrt", "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"orthographic\"\nWorldBegin\n"
                              "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
                              "Shape \"trianglemesh\" \"point3 P\" [ -200 -200 0  200 -200 0  200 200 0  -200 200 0 ] "
                              "\"integer indices\" [ 0 1 2 0 2 3 ]\nAttributeBegin\nTranslate 0 0 2\n"
                              "LightSource \"goniometric\" \"string filename\" \"" DATA "cosine.ies\"\nAttributeEnd\n");
    CHECK(scene != NULL);
    if (!scene) return;
    pn_vpl_settings vs = {20001, 1, 0.05f, 5};
    pn_vpl_set set;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &vs, &set, &err) == PN_OK);
    double sum = 0.0, sum2 = 0.0;
    int omni = 0;
    for (uint32_t i = 0; i < set.count; i++) {
        const pn_vpl *v = &set.vpls[i];
        if (v->kind == PN_VPL_OMNI) {
            omni++;
            continue;
        }
        double e = PI_D * (double)v->intensity.y;
        sum += e;
        sum2 += e * e;
    }
    CHECK(omni == 1);
    double n = (double)set.paths, se = sqrt(fmax(0.0, sum2 * n - sum * sum) / n);
    pn_photometry *p = read_data("cosine.ies");
    double want = p ? 0.5 * p->lumens * (1.0 - 1e-4) : 0.0;
    pn_photometry_free(p);
    fprintf(stderr, "  first-bounce power %.2f lm, kd x lumens %.2f lm (se %.2f)\n", sum, want, se);
    CHECK_MSG(fabs(sum - want) <= 5.0 * se + 1e-3 * want, "first-bounce power %g, expected %g (se %g)", sum, want, se);
    pn_vpl_set_free(&set);
    pn_scene_free(scene);
}

/* The light BVH's bound and ias's leaf culling of a narrow beam (lit to gamma = 15 degrees):
 * wherever the beam gives a receiver light, the bound's importance is positive and the leaf is
 * not culled; well outside the cone the importance is 0 and the leaf culled, for a luminaire
 * turned 50 degrees. */
static void test_bvh_cone_bounds_the_beam(void) {
    const pn_light *l = NULL;
    pn_scene scene = load_luminaire("cone.pbrt", "Translate 0 0 2\nRotate 50 1 1 0", "beam.ies", &l);
    if (!l) {
        pn_scene_free(scene);
        return;
    }
    pn_light_bvh_bounds b;
    CHECK(pn_light_bounds_of(scene->lights, l, &b));
    const pn_gonio *g = &scene->lights->gonios[l->env];
    int lit = 0, missed = 0, pruned = 0, culled_lit = 0, culled_far = 0;
    uint64_t s = 3;
    for (int k = 0; k < 20000; k++) {
        double u[3] = {rnd(&s), rnd(&s), rnd(&s)};
        double z = 1.0 - 2.0 * u[0], r = sqrt(fmax(0.0, 1.0 - z * z)), ph = 2.0 * PI_D * u[1];
        vec3 w = v3((float)(r * cos(ph)), (float)(r * sin(ph)), (float)z);
        vec3 p = v3_add(l->p, v3_scale(w, (float)(0.5 + 3.0 * u[2])));
        vec3 n = v3_neg(w); /* facing the light */
        float e = pn_light_irradiance_estimate(scene->lights, l, p, n);
        float imp = pn_light_bounds_importance(&b, p, n);
        bool culled = pn_cluster_light_culled(l, p, n);
        if (e > 0.0f) {
            lit++;
            if (!(imp > 0.0f)) missed++;
            if (culled) culled_lit++;
        }
        if (v3_dot(w, g->nadir) < cosf(20.0f * (float)PI_D / 180.0f)) {
            if (imp == 0.0f) pruned++;
            if (culled) culled_far++;
        }
    }
    CHECK(lit > 100);
    CHECK_MSG(missed == 0, "%d of %d lit receivers have importance 0", missed, lit);
    CHECK_MSG(culled_lit == 0, "ias culls %d of %d lit receivers", culled_lit, lit);
    CHECK_MSG(culled_far > 15000, "ias culls only %d receivers outside the cone", culled_far);
    CHECK_MSG(pruned > 15000, "only %d receivers outside the cone pruned", pruned);
    pn_scene_free(scene);
}

/* docs/luminaires.md's aiming: LM-72 Orient 90 then Tilt 90 (Rotate 90 0 0 1, Rotate -90 0 1 0)
 * turns a luminaire's nadir from -z to due north, +y, and its C = 0 axis (+x, its front) up. */
static void test_aiming_convention(void) {
    const pn_light *l = NULL;
    pn_scene scene = load_luminaire("aim.pbrt", "Translate 0 0 2\nRotate 90 0 0 1\nRotate -90 0 1 0", "street.ies", &l);
    if (l) {
        const pn_gonio *g = &scene->lights->gonios[l->env];
        CHECK_NEAR(g->nadir.x, 0.0, 1e-6);
        CHECK_NEAR(g->nadir.y, 1.0, 1e-6);
        CHECK_NEAR(g->nadir.z, 0.0, 1e-6);
        /* gamma 60 in the C = 0 plane (street_cd's brighter side) now lies between north and up */
        double g60 = 60.0 * PI_D / 180.0;
        vec3 w = v3(0.0f, (float)cos(g60), (float)sin(g60));
        double want = street_cd(60.0, 0.0) / (scene->photometries[0]->peak_cd);
        CHECK_NEAR(pn_gonio_factor(scene->lights, l, w), want, 1e-5);
    }
    pn_scene_free(scene);
}

/* ---- integrators ---------------------------------------------------------------------------------- */

/* Every integrator (and every driver, with the reference integrator) renders the street light
 * over the plane; with one plane there is no interreflection, so the VPL integrators' total
 * equals the direct light: all means agree with the reference. The light BVH sampler's cone bound (a downlight) is exercised too. */
static void test_every_integrator_renders_it(void) {
    pn_scene scene = load_text("all.pbrt", plane_scene(16, "Translate 0.3 0 1.5",
                                                       "LightSource \"goniometric\" \"string filename\" \"" DATA
                                                       "street.ldt\" \"float power\" [ 2000 ]"));
    CHECK(scene != NULL);
    if (!scene) return;
    enum { NM = 12 };
    pn_integrator_kind kinds[NM] = {PN_INTEGRATOR_REFERENCE, PN_INTEGRATOR_REFERENCE,  PN_INTEGRATOR_IAS,
                                    PN_INTEGRATOR_CONTOUR,   PN_INTEGRATOR_CONTOUR_MC, PN_INTEGRATOR_VPL,
                                    PN_INTEGRATOR_LIGHTCUTS, PN_INTEGRATOR_ILLUMCUT,   PN_INTEGRATOR_REFERENCE,
                                    PN_INTEGRATOR_REFERENCE, PN_INTEGRATOR_REFERENCE,  PN_INTEGRATOR_REFERENCE};
    pn_driver_kind drivers[NM] = {PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT,
                                  PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT, PN_DRIVER_DEFAULT,
                                  PN_DRIVER_FULL,    PN_DRIVER_DCM,     PN_DRIVER_PAINTER, PN_DRIVER_UNIFORM};
    const char *names[NM] = {"reference", "reference bvh", "ias",  "contour", "contour-mc", "vpl",
                             "lightcuts", "illumcut",      "full", "dcm",     "painter",    "uniform"};
    double mean[NM] = {0};
    for (int m = 0; m < NM; m++) {
        pn_render_settings rs;
        memset(&rs, 0, sizeof rs);
        rs.integrator = kinds[m];
        rs.driver = drivers[m];
        rs.threads = 2;
        rs.seed = 5;
        rs.spp = kinds[m] == PN_INTEGRATOR_IAS ? 0 : 8;
        rs.options = pn_options_new();
        if (m == 1) CHECK(pn_options_set(test_context(), rs.options, "light-sampler", "bvh") == PN_OK);
        if (m >= 5 && m <= 7) {
            CHECK(pn_options_set_int(test_context(), rs.options, "vpls", 300) == PN_OK);
            CHECK(pn_options_set_int(test_context(), rs.options, "vpl-depth", 1) == PN_OK);
        }
        pn_image img = NULL;
        pn_status st = pn_render(test_context(), scene, &rs, &img, NULL);
        pn_options_free(rs.options);
        CHECK_MSG(st == PN_OK, "%s: %s", names[m], pn_context_error_message(test_context()));
        if (img) {
            const float *px = pn_image_layer_data(img, 0);
            for (int i = 0; i < 16 * 16; i++)
                mean[m] += 0.2126 * (double)px[3 * i] + 0.7152 * (double)px[3 * i + 1] + 0.0722 * (double)px[3 * i + 2];
            mean[m] /= 256.0;
        }
        pn_image_free(img);
    }
    CHECK(mean[0] > 0.0);
    for (int m = 1; m < NM; m++)
        CHECK_MSG(fabs(mean[m] / mean[0] - 1.0) < 0.02, "%s: mean %g, reference %g", names[m], mean[m], mean[0]);
    pn_scene_free(scene);
}

/* ---- penumbra info ---------------------------------------------------------------------------------- */

static void read_text(const char *path, char *out, size_t size) {
    out[0] = '\0';
    FILE *f = fopen(path, "r");
    if (!f) return;
    size_t n = fread(out, 1, size - 1, f);
    out[n] = '\0';
    fclose(f);
}

/* Each luminaire's lumens integrated from its distribution next to the file's stated lumens,
 * through the library and the CLI. */
static void test_info_lumens(void) {
    const char *text =
        plane_scene(4, "Translate 0 0 2",
                    "LightSource \"goniometric\" \"string filename\" \"" DATA "cosine.ies\"\n"
                    "LightSource \"goniometric\" \"string filename\" \"" DATA "street.ldt\" \"float power\" [ 500 ]\n"
                    "LightSource \"goniometric\" \"string filename\" \"" DATA
                    "tilt.ies\" \"float tilt\" [ 45 ] \"float scale\" [ 2 ]");
    pn_scene scene = load_text("info.pbrt", text);
    CHECK(scene != NULL);
    if (!scene) return;
    CHECK(pn_scene_luminaire_count(scene) == 3);
    pn_luminaire_info li[3];
    for (uint32_t i = 0; i < 3; i++) CHECK(pn_scene_luminaire_get(scene, i, &li[i]) == PN_OK);
    CHECK(pn_scene_luminaire_get(scene, 3, &li[0]) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_NEAR(li[0].stated_lumens, 1000.0, 1e-9);
    CHECK(fabs(li[0].lumens / 1000.0 - 1.0) < 0.01);
    CHECK_NEAR(li[1].lumens, 500.0, 1e-6);
    CHECK(li[1].file_lumens > 500.0);
    CHECK_NEAR(li[1].stated_luminaire_lumens, 1000.0, 1e-9);
    CHECK_NEAR(li[2].lumens, 2.0 * 0.9 * li[2].file_lumens, 1e-6); /* scale 2, tilt factor 0.9 at 45 */
    pn_scene_free(scene);
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s info %s >%s 2>&1", PN_CLI_PATH, tpath("info.pbrt"), tpath("info.txt"));
    int status = system(cmd);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    read_text(tpath("info.txt"), out, sizeof out);
    CHECK_MSG(strstr(out, "luminaires     3") && strstr(out, "street.ldt: 500.0 lm emitted") &&
                  strstr(out, "1000.0 lm of lamps stated") && strstr(out, "1000.0 lm luminaire (LOR) stated"),
              "info printed:\n%s", out);
}

/* ---- ies2goniometric ---------------------------------------------------------------------------------- */

/* The luminaire and its pbrt-v4 goniometric image, under the same turned transform, render the
 * same plane: mean relative difference below 1 %, every pixel within 3 % (the image is looked
 * up nearest-texel, as pbrt-v4 does, the file bilinearly); the image's 4 pi mean is the
 * luminaire's lumens. */
static void test_goniometric_image_renders_the_same(void) {
    pn_image img = NULL;
    CHECK(pn_photometry_goniometric_image(test_context(), DATA "street.ies", 512, &img) == PN_OK);
    if (!img) return;
    const float *px = pn_image_layer_data(img, 0);
    double sum = 0.0;
    for (int i = 0; i < 512 * 512; i++) sum += (double)px[3 * i];
    pn_photometry *p = read_data("street.ies");
    if (p) {
        double lm = 4.0 * PI_D * sum / (512.0 * 512.0);
        CHECK_MSG(fabs(lm / p->lumens - 1.0) < 0.005, "image %g lm, file %g lm", lm, p->lumens);
        pn_photometry_free(p);
    }
    CHECK(pn_image_write(test_context(), img, tpath("street.exr"), 0.0f) == PN_OK);
    pn_image_free(img);
    enum { R = 24 };
    static float a[3 * R * R], b[3 * R * R];
    const char *xf = "Translate 0.2 -0.1 1.2\nRotate 35 0 0 1\nRotate 15 1 0 0";
    char light[600];
    snprintf(light, sizeof light, "LightSource \"goniometric\" \"string filename\" \"%s\"", tpath("street.exr"));
    const char *which[2] = {"LightSource \"goniometric\" \"string filename\" \"" DATA "street.ies\"", light};
    float *out[2] = {a, b};
    for (int k = 0; k < 2; k++) {
        pn_scene scene = load_text(k ? "gimg.pbrt" : "gies.pbrt", plane_scene(R, xf, which[k]));
        CHECK(scene != NULL);
        if (!scene) return;
        CHECK(render_scene(scene, 4, out[k], 3 * R * R));
        pn_scene_free(scene);
    }
    double rel = 0.0, worst = 0.0, total = 0.0;
    for (int i = 0; i < 3 * R * R; i++) {
        double d = fabs((double)a[i] - (double)b[i]);
        rel += d;
        total += (double)a[i];
        worst = fmax(worst, d / fmax((double)a[i], 1e-3));
    }
    fprintf(stderr, "  ies vs goniometric image: mean relative difference %.3g%%, worst pixel %.3g%%\n",
            100.0 * rel / total, 100.0 * worst);
    CHECK(total > 0.0);
    CHECK(rel / total < 0.01);
    CHECK(worst < 0.03);
    /* the command: writes the image (exit 0), refuses a missing -o (2) and a bad file (3) */
    struct {
        const char *args;
        int code;
    } runs[] = {{"ies2goniometric " DATA "street.ldt -o %s --resolution 64", 0},
                {"ies2goniometric " DATA "street.ldt", 2},
                {"ies2goniometric " DATA "bad_negative.ies -o %s", 3}};
    for (int k = 0; k < 3; k++) {
        char args[800], cmd[1200];
        snprintf(args, sizeof args, runs[k].args, tpath(k ? "never.exr" : "cli.exr"));
        snprintf(cmd, sizeof cmd, "%s %s >/dev/null 2>&1", PN_CLI_PATH, args);
        int status = system(cmd);
        CHECK_MSG(WIFEXITED(status) && WEXITSTATUS(status) == runs[k].code, "%s: exit %d", args, WEXITSTATUS(status));
    }
    pn_image back = NULL;
    CHECK(pn_image_read(test_context(), tpath("cli.exr"), &back) == PN_OK);
    if (back) CHECK(pn_image_width(back) == 64);
    pn_image_free(back);
    FILE *never = fopen(tpath("never.exr"), "rb");
    CHECK(never == NULL);
    if (never) fclose(never);
}

/* ---- bad files ------------------------------------------------------------------------------------ */

static void test_bad_files_refused(void) {
    struct {
        const char *file;
        int line, col; /* col: the offending value's, or 1 for a whole-line field */
        const char *says;
    } cases[] = {
        {"bad_truncated.ies", 9, 1, "ends before candela value 1 of 3"},
        {"bad_negative.ies", 10, 17, "is negative"},
        {"bad_nan.ies", 10, 17, "not a finite number"},
        {"bad_counts.ies", 10, 25, "unexpected"},
        {"bad_nonmonotonic.ies", 8, 6, "must increase"},
        {"bad_type_a.ies", 6, 14, "type A"},
        {"bad_tilt_file.ies", 5, 1, "TILT=lamp.tlt"},
        {"bad_symmetry.ies", 9, 3, "match no LM-63 symmetry"},
        {"bad_no_tilt.ies", 3, 1, "no \"TILT=\" line"},
        {"bad_truncated.ldt", 60, 1, "ends before C-angle"},
        {"bad_negative.ldt", 201, 1, "is negative"},
        {"bad_isym.ldt", 3, 1, "Isym"},
        {"bad_counts.ldt", 585, 1, "unexpected"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char path[512], want[640];
        snprintf(path, sizeof path, DATA "%s", cases[k].file);
        snprintf(want, sizeof want, "%s:%d:%d: ", path, cases[k].line, cases[k].col);
        pn_err err;
        pn_err_init(&err);
        pn_photometry *p = NULL;
        pn_status st = pn_photometry_read(path, path, &p, &err);
        CHECK_MSG(st == PN_ERROR_BAD_INPUT && !p, "%s: status %d", cases[k].file, (int)st);
        CHECK_MSG(strncmp(err.message, want, strlen(want)) == 0 && strstr(err.message, cases[k].says),
                  "%s: message \"%s\", wanted \"%s...%s\"", cases[k].file, err.message, want, cases[k].says);
        pn_photometry_free(p);
    }
    /* Through a scene and the CLI: exit status 3, the file's location first. */
    const char *scene = plane_scene(4, "", "LightSource \"goniometric\" \"string filename\" \"" DATA "bad_nan.ies\"");
    write_file("bad.pbrt", scene);
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s info %s >%s 2>&1", PN_CLI_PATH, tpath("bad.pbrt"), tpath("bad.txt"));
    int status = system(cmd);
    CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 3);
    FILE *f = fopen(tpath("bad.txt"), "r");
    char out[2048] = "";
    if (f) {
        size_t n = fread(out, 1, sizeof out - 1, f);
        out[n] = '\0';
        fclose(f);
    }
    CHECK_MSG(strstr(out, "bad_nan.ies:10:17: ") != NULL, "CLI said: %s", out);
}

PN_TESTS(TEST(test_lumens_match_stated), TEST(test_symmetry_forms_agree), TEST(test_ies_and_eulumdat_agree),
         TEST(test_type_b), TEST(test_tilt_table), TEST(test_mutated_files_never_crash),
         TEST(test_illuminance_closed_form), TEST(test_render_units), TEST(test_symmetry_forms_render_identically),
         TEST(test_emission_sampling), TEST(test_vpl_first_bounce), TEST(test_bvh_cone_bounds_the_beam),
         TEST(test_aiming_convention), TEST(test_every_integrator_renders_it), TEST(test_bad_files_refused),
         TEST(test_info_lumens), TEST(test_goniometric_image_renders_the_same))
