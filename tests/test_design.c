/* test_design.c — lighting design (docs/lighting-design.md): the CIE overcast sky in absolute
 * units, calculation points against closed forms, the grid against the image's illuminance AOV,
 * thin glass against the Fresnel slab transmittance, daylight factor, the CLI's CSV / JSON /
 * point-file errors and false colour. */
#define PN_SCENE_FILES_PREFIX "pn_test_design"
#include "harness.h"
#include "scene_files.h"

#include "core/photometry.h"
#include "io/image.h"
#include "lights/lights.h"
#include "render/camera.h"
#include "scene/scene.h"
#include "scene/sky.h"

#include <cjson/cJSON.h>
#include <sys/wait.h>

#define CLI PN_CLI_PATH

static const char *header =
    "LookAt 0 0 5  0 0 0  0 1 0\n"
    "Camera \"orthographic\" \"float screenwindow\" [-2 2 -2 2]\n"
    "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16 \"string filename\" \"x.exr\"\n"
    "PixelFilter \"box\" \"float xradius\" 0.5 \"float yradius\" 0.5\n"
    "WorldBegin\n";
static const char *floor_quad = "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
                                "Shape \"trianglemesh\" \"point3 P\" [-8 -8 0  8 -8 0  8 8 0  -8 8 0] "
                                "\"integer indices\" [0 1 2 0 2 3]\n";

static pn_scene load_text(const char *name, const char *body) {
    static char text[8192];
    snprintf(text, sizeof text, "%s%s%s", header, body, floor_quad);
    write_file(name, text);
    pn_scene scene = NULL;
    pn_status st = pn_scene_load(test_context(), tpath(name), &scene);
    CHECK_MSG(st == PN_OK, "%s: %s", name, pn_context_error_message(test_context()));
    return scene;
}

/* Illuminance at points with the given integrator name and spp. */
static pn_status points_lux(pn_scene scene, const char *integrator, uint32_t spp, int threads,
                            const pn_illuminance_point *pts, int n, double *lux, const char *opt, const char *val) {
    pn_render_settings s;
    memset(&s, 0, sizeof s);
    int m = pn_method_find(PN_METHOD_INTEGRATOR, integrator);
    s.integrator = (pn_integrator_kind)pn_method_get(m)->kind;
    s.spp = spp;
    s.threads = threads;
    s.seed = 7;
    pn_options o = pn_options_new();
    if (opt) pn_options_set(test_context(), o, opt, val);
    /* The VPL integrators' direct-light set (the lights themselves): the quantity the closed forms
     * give, and a handful of VPLs instead of the default 600000. */
    if (strcmp(integrator, "reference") != 0 && strcmp(integrator, "ias") != 0 &&
        !(opt && strcmp(opt, "vpl-direct-only") == 0))
        pn_options_set(test_context(), o, "vpl-direct-only", "1");
    s.options = o;
    pn_status st = pn_illuminance(test_context(), scene, &s, pts, n, lux);
    pn_options_free(o);
    return st;
}

static pn_illuminance_point up_point(float x, float y, float z) {
    pn_illuminance_point p = {{x, y, z}, {0, 0, 1}};
    return p;
}

/* ---- the sky ------------------------------------------------------------------------------- */

static void test_overcast_sky_illuminance(void) {
    pn_scene scene = load_text("sky.pbrt", "LightSource \"infinite\" \"string sky\" \"cie-overcast\" "
                                           "\"float illuminance\" 12000\n");
    if (!scene) return;
    pn_illuminance_point p[2] = {up_point(0.3f, -0.2f, 0.0f), up_point(-1.0f, 1.0f, 0.0f)};
    double lux[2];
    CHECK(points_lux(scene, "reference", 1024, 2, p, 2, lux, NULL, NULL) == PN_OK);
    for (int i = 0; i < 2; i++) CHECK_NEAR(lux[i] / 12000.0, 1.0, 0.005);
    /* The VPL integrators' direct-light set samples the same map. */
    CHECK(points_lux(scene, "vpl", 1, 2, p, 1, lux, "vpl-direct-only", "1") == PN_OK);
    CHECK_NEAR(lux[0] / 12000.0, 1.0, 0.005);
    pn_scene_free(scene);
}

static void test_overcast_sky_luminance_profile(void) {
    pn_scene scene = load_text("sky2.pbrt", "LightSource \"infinite\" \"string sky\" \"cie-overcast\" "
                                            "\"float illuminance\" 10000\n");
    if (!scene) return;
    const pn_lights *L = scene->lights;
    CHECK(L->env_count == 1);
    const double lz = pn_sky_overcast_zenith(10000.0);
    CHECK_NEAR(lz, 9.0 * 10000.0 / (7.0 * 3.14159265358979), 1e-6);
    double worst = 0.0;
    for (int k = 1; k <= 18; k++) {
        double h = (double)k * 5.0 * 3.14159265358979 / 180.0;
        for (int a = 0; a < 8; a++) {
            double phi = a * 0.785398;
            vec3 d = v3((float)(cos(h) * cos(phi)), (float)(cos(h) * sin(phi)), (float)sin(h));
            double got = (double)pn_photometric(pn_lights_environment_radiance(L, d));
            double want = lz * (1.0 + 2.0 * sin(h)) / 3.0;
            worst = fmax(worst, fabs(got / want - 1.0));
        }
    }
    CHECK_MSG(worst < 0.01, "worst relative luminance error %g", worst);
    /* Below the horizon the sky is black. */
    CHECK(v3_is_zero(pn_lights_environment_radiance(L, v3(0.6f, 0.0f, -0.8f))));
    pn_scene_free(scene);
}

static void test_sky_bad_input(void) {
    write_file("badsky.pbrt",
               "WorldBegin\nLightSource \"infinite\" \"string sky\" \"perez\" \"float illuminance\" 1\n");
    pn_scene scene = NULL;
    CHECK(pn_scene_load(test_context(), tpath("badsky.pbrt"), &scene) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(pn_context_error_message(test_context()), "badsky.pbrt:2:");
    CHECK_STR_CONTAINS(pn_context_error_message(test_context()), "unknown sky");
    write_file("badsky2.pbrt", "WorldBegin\nLightSource \"infinite\" \"string sky\" \"cie-overcast\"\n");
    pn_context fresh = pn_context_new(); /* a context keeps its first error's message */
    pn_context_set_log(fresh, silent_log, NULL);
    CHECK(pn_scene_load(fresh, tpath("badsky2.pbrt"), &scene) == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(pn_context_error_message(fresh), "badsky2.pbrt:2:");
    CHECK_STR_CONTAINS(pn_context_error_message(fresh), "positive \"float illuminance\"");
    pn_context_free(fresh);
}

/* ---- the CIE clear sky with sun ------------------------------------------------------------- */

/* The sun's position against published values: NREL's SPA report (Reda & Andreas 2004, its
 * example: 17 October 2003, 12:30:30 local standard time, UTC-7, 39.742476 N, 105.1786 W:
 * topocentric zenith angle 50.11162, azimuth 194.34024 degrees) and Meeus's example 25.a (13
 * October 1992, 0h: apparent declination -7.78507 degrees). */
static void test_sun_position_published(void) {
    pn_sun_position s = pn_sun_position_at(2003, 10, 17, 12.5 + 30.0 / 3600.0, -7.0, 39.742476, -105.1786);
    CHECK_MSG(fabs(s.zenith_deg - 50.11162) < 0.1, "zenith %.5f", s.zenith_deg);
    CHECK_MSG(fabs(s.azimuth_deg - 194.34024) < 0.1, "azimuth %.5f", s.azimuth_deg);
    pn_sun_position m = pn_sun_position_at(1992, 10, 13, 0.0, 0.0, 0.0, 0.0);
    CHECK_MSG(fabs(m.declination_deg + 7.78507) < 0.01, "declination %.5f", m.declination_deg);
    /* Southern hemisphere, winter morning: the sun is in the north-east (azimuth between 0 and 90). */
    pn_sun_position b = pn_sun_position_at(2024, 6, 21, 10.0, 10.0, -33.87, 151.21);
    CHECK(b.azimuth_deg > 0.0 && b.azimuth_deg < 90.0 && b.zenith_deg > 50.0 && b.zenith_deg < 80.0);
}

/* The CIE standard general sky of type 12, written out here from CIE S 011/E:2003 (gradation
 * group V, indicatrix group 4: a = -1, b = -0.32, c = 10, d = -3, e = 0.45), relative to the
 * zenith. */
static double cie12(double z, double chi, double zs) {
    double phi = z < 3.14159265358979 / 2.0 ? 1.0 - exp(-0.32 / cos(z)) : 1.0;
    double f = 1.0 + 10.0 * (exp(-3.0 * chi) - exp(-3.0 * 3.14159265358979 / 2.0)) + 0.45 * cos(chi) * cos(chi);
    double f_zs = 1.0 + 10.0 * (exp(-3.0 * zs) - exp(-3.0 * 3.14159265358979 / 2.0)) + 0.45 * cos(zs) * cos(zs);
    return f * phi / (f_zs * (1.0 - exp(-0.32)));
}

static const char *clear_sky = "LightSource \"infinite\" \"string sky\" \"cie-clear\" \"float illuminance\" 15000 "
                               "\"float sunilluminance\" 60000 \"string date\" \"2024-06-21\" \"float time\" 10 "
                               "\"float timezone\" 2 \"float latitude\" 48.14 \"float longitude\" 11.58\n";

static void test_clear_sky_luminance_and_sun(void) {
    pn_scene scene = load_text("clear.pbrt", clear_sky);
    if (!scene) return;
    const pn_lights *L = scene->lights;
    CHECK(L->env_count == 1);
    pn_sun_position sun = pn_sun_position_at(2024, 6, 21, 10.0, 2.0, 48.14, 11.58);
    const double deg = 3.14159265358979 / 180.0, zs = sun.zenith_deg * deg, as = sun.azimuth_deg * deg;
    /* Light frame = world: +z the zenith, +y north, +x east. */
    vec3 sd = v3((float)(sin(zs) * sin(as)), (float)(sin(zs) * cos(as)), (float)cos(zs));
    int distant = -1;
    for (int i = 0; i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_DISTANT) distant = i;
    CHECK(distant >= 0);
    if (distant >= 0) {
        CHECK(v3_dot(L->lights[distant].n, sd) > 0.99999f);
        CHECK_NEAR(pn_photometric(L->lights[distant].emit), 60000.0 / cos(zs), 1e-3 * 60000.0 / cos(zs));
    }
    /* The distribution's shape: luminance over the formula, the same ratio everywhere (its
     * absolute value is the horizontal illuminance's, checked below). */
    double ratio[17 * 12], mean = 0.0, worst = 0.0;
    int n = 0;
    for (int k = 1; k <= 17; k++) {
        double z = (double)k * 5.0 * deg;
        for (int a = 0; a < 12; a++) {
            double az = a * 30.0 * deg;
            vec3 d = v3((float)(sin(z) * sin(az)), (float)(sin(z) * cos(az)), (float)cos(z));
            double chi = acos(fmin(1.0, (double)v3_dot(d, sd)));
            if (chi < 10.0 * deg) continue; /* the circumsolar peak varies within a texel */
            ratio[n] = (double)pn_photometric(pn_lights_environment_radiance(L, d)) / cie12(z, chi, zs);
            mean += ratio[n++];
        }
    }
    CHECK(n > 150);
    mean /= n;
    for (int i = 0; i < n; i++) worst = fmax(worst, fabs(ratio[i] / mean - 1.0));
    /* The map is read by nearest texel (512 x 512 equal-area texels, 0.4 degree across, each the
     * mean of 4 x 4 points): 1.04% at worst here, where the indicatrix is steep. */
    CHECK_MSG(worst < 0.015, "worst relative luminance error %g", worst);
    /* Horizontal illuminance: sky (diffuse) and sun (direct) as set. */
    pn_illuminance_point p[2] = {up_point(0.3f, -0.2f, 0.0f), up_point(-1.0f, 1.0f, 0.0f)};
    double lux[2];
    CHECK(points_lux(scene, "reference", 1024, 2, p, 2, lux, NULL, NULL) == PN_OK);
    for (int i = 0; i < 2; i++) CHECK_MSG(fabs(lux[i] / 75000.0 - 1.0) < 0.005, "point %d: %g lx", i, lux[i]);
    pn_scene_free(scene);
    /* Without "sunilluminance": the sky alone, no distant light. */
    scene = load_text("clear2.pbrt", "LightSource \"infinite\" \"string sky\" \"cie-clear\" \"float illuminance\" "
                                     "15000 \"string date\" \"2024-06-21\" \"float time\" 10 \"float timezone\" 2 "
                                     "\"float latitude\" 48.14 \"float longitude\" 11.58\n");
    if (!scene) return;
    CHECK(scene->lights->count == 1);
    CHECK(points_lux(scene, "reference", 1024, 2, p, 2, lux, NULL, NULL) == PN_OK);
    for (int i = 0; i < 2; i++)
        CHECK_MSG(fabs(lux[i] / 15000.0 - 1.0) < 0.005, "sky alone, point %d: %g lx", i, lux[i]);
    pn_scene_free(scene);
}

static void test_clear_sky_bad_input(void) {
    const char *cases[3][2] = {
        {"LightSource \"infinite\" \"string sky\" \"cie-clear\" \"float illuminance\" 1000 \"float time\" 10 "
         "\"float latitude\" 48 \"float longitude\" 11\n",
         "\"string date\" as YYYY-MM-DD"},
        {"LightSource \"infinite\" \"string sky\" \"cie-clear\" \"float illuminance\" 1000 \"string date\" "
         "\"2024-06-21\" \"float time\" 10 \"float longitude\" 11\n",
         "\"float latitude\" in [-90, 90]"},
        {"LightSource \"infinite\" \"string sky\" \"cie-clear\" \"float illuminance\" 1000 \"string date\" "
         "\"2024-12-21\" \"float time\" 23 \"float timezone\" 1 \"float latitude\" 48 \"float longitude\" 11\n",
         "the sun is below the horizon"}};
    for (int k = 0; k < 3; k++) {
        char name[32], text[1024];
        snprintf(name, sizeof name, "badclear%d.pbrt", k);
        snprintf(text, sizeof text, "WorldBegin\n%s", cases[k][0]);
        write_file(name, text);
        pn_context fresh = pn_context_new();
        pn_context_set_log(fresh, silent_log, NULL);
        pn_scene scene = NULL;
        CHECK(pn_scene_load(fresh, tpath(name), &scene) == PN_ERROR_BAD_INPUT);
        CHECK_STR_CONTAINS(pn_context_error_message(fresh), ":2:");
        CHECK_STR_CONTAINS(pn_context_error_message(fresh), cases[k][1]);
        pn_context_free(fresh);
    }
}

/* ---- points against closed forms ------------------------------------------------------------- */

/* A point light of 1000 cd at (0.4, -0.3, 2): E = I cos(theta) / d^2 on the floor. */
static const char *point_light = "LightSource \"point\" \"point3 from\" [0.4 -0.3 2] \"rgb I\" "
                                 "[1000 1000 1000]\n";

static double point_closed_form(const pn_illuminance_point *p) {
    double dx = 0.4 - (double)p->p[0], dy = -0.3 - (double)p->p[1], dz = 2.0 - (double)p->p[2];
    double d2 = dx * dx + dy * dy + dz * dz;
    return 1000.0 * (dz / sqrt(d2)) / d2;
}

static void test_grid_point_light_closed_form(void) {
    pn_scene scene = load_text("point.pbrt", point_light);
    if (!scene) return;
    enum { N = 25 };
    pn_illuminance_point p[N];
    for (int i = 0; i < N; i++) p[i] = up_point(-2.0f + (float)(i % 5), -2.0f + (float)(i / 5), 0.0f);
    double lux[N];
    const char *methods[3] = {"reference", "vpl", "lightcuts"};
    for (int m = 0; m < 3; m++) {
        CHECK(points_lux(scene, methods[m], 1, 2, p, N, lux, NULL, NULL) == PN_OK);
        for (int i = 0; i < N; i++) CHECK_NEAR(lux[i] / point_closed_form(&p[i]), 1.0, 0.005);
    }
    /* Points are independent: the same numbers for 1 and 2 threads, and in any order. */
    double one[N];
    CHECK(points_lux(scene, "reference", 4, 1, p, N, one, NULL, NULL) == PN_OK);
    CHECK(points_lux(scene, "reference", 4, 2, p, N, lux, NULL, NULL) == PN_OK);
    CHECK(memcmp(one, lux, sizeof one) == 0);
    /* A normal facing away sees nothing; ias cannot evaluate points. */
    pn_illuminance_point down = {{0, 0, 0.5f}, {0, 0, -1}};
    CHECK(points_lux(scene, "reference", 4, 1, &down, 1, lux, NULL, NULL) == PN_OK);
    CHECK(lux[0] == 0.0);
    CHECK(points_lux(scene, "ias", 4, 1, &down, 1, lux, NULL, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_scene_free(scene);
}

/* The illuminance AOV of a top-down orthographic render against points at the pixels' floor
 * positions (the camera's own ray through each pixel centre), with a spot light. */
static void test_grid_matches_illuminance_aov(void) {
    pn_scene scene = load_text("spot.pbrt", "LightSource \"spot\" \"point3 from\" [0.5 0.2 1.5] \"point3 to\" "
                                            "[0 0 0] \"rgb I\" [1366 1366 1366] \"float coneangle\" 50 "
                                            "\"float conedeltaangle\" 15\n");
    if (!scene) return;
    const int W = 16, H = 16;
    pn_render_settings s;
    memset(&s, 0, sizeof s);
    s.spp = 64;
    s.threads = 2;
    s.aovs = PN_AOV_ILLUMINANCE | PN_AOV_LUMINANCE;
    pn_image img = NULL;
    CHECK(pn_render(test_context(), scene, &s, &img, NULL) == PN_OK);
    if (!img) return;
    const float *lux_aov = NULL, *lum_aov = NULL;
    for (int l = 0; l < pn_image_layer_count(img); l++) {
        if (strcmp(pn_image_layer_name(img, l), "illuminance") == 0) lux_aov = pn_image_layer_data(img, l);
        if (strcmp(pn_image_layer_name(img, l), "luminance") == 0) lum_aov = pn_image_layer_data(img, l);
    }
    CHECK(lux_aov && lum_aov);
    pn_camera cam;
    const float crop[4] = {0, 1, 0, 1};
    CHECK(pn_camera_setup(&scene->camera, W, H, crop, &cam));
    /* The AOV's expectation is the mean of E over the pixel (box filter of radius 1/2): the
     * points are 4 x 4 per pixel, averaged. */
    enum { SUB = 4 };
    static pn_illuminance_point p[16 * 16 * SUB * SUB];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int k = 0; k < SUB * SUB; k++) {
                vec3 o, d;
                pn_camera_ray(&cam, (float)x + ((float)(k % SUB) + 0.5f) / SUB,
                              (float)y + ((float)(k / SUB) + 0.5f) / SUB, 0.5f, 0.5f, &o, &d);
                float t = -o.z / d.z;
                p[(y * W + x) * SUB * SUB + k] = up_point(o.x + t * d.x, o.y + t * d.y, 0.0f);
            }
    static double sub[16 * 16 * SUB * SUB];
    double lux[16 * 16];
    CHECK(points_lux(scene, "reference", 16, 2, p, W * H * SUB * SUB, sub, NULL, NULL) == PN_OK);
    for (int i = 0; i < W * H; i++) {
        lux[i] = 0.0;
        for (int k = 0; k < SUB * SUB; k++) lux[i] += sub[i * SUB * SUB + k] / (SUB * SUB);
    }
    const float *beauty = pn_image_layer_data(img, 0);
    int lit = 0;
    for (int i = 0; i < W * H && lux_aov; i++) {
        CHECK_NEAR(lux_aov[i], lux[i], 0.02 * lux[i] + 2.0);
        lit += lux[i] > 100.0;
        /* luminance = Y of the beauty (docs/units.md); a Lambertian floor of reflectance 0.5: L = 0.5 E / pi */
        double y = 0.2126 * beauty[3 * i] + 0.7152 * beauty[3 * i + 1] + 0.0722 * beauty[3 * i + 2];
        CHECK_NEAR(lum_aov[i], y, 1e-3 * lum_aov[i] + 1e-4);
        CHECK_NEAR(lum_aov[i], 0.5 * lux_aov[i] / 3.14159265358979, 1e-3 * lum_aov[i] + 1e-3);
    }
    CHECK(lit > 20);
    pn_image_free(img);
    pn_scene_free(scene);
}

/* The VPL integrators' illuminance AOV (total light; here direct only, the spot being one exact
 * VPL) against the reference's, pixel for pixel: the same quantity by other estimators. */
static const float *layer_named(pn_image img, const char *name) {
    for (int l = 0; l < pn_image_layer_count(img); l++)
        if (strcmp(pn_image_layer_name(img, l), name) == 0) return pn_image_layer_data(img, l);
    return NULL;
}

static void test_vpl_illuminance_aov_matches_reference(void) {
    pn_scene scene = load_text("spot2.pbrt", "LightSource \"spot\" \"point3 from\" [0.5 0.2 1.5] \"point3 to\" "
                                             "[0 0 0] \"rgb I\" [1366 1366 1366] \"float coneangle\" 50 "
                                             "\"float conedeltaangle\" 15\n");
    if (!scene) return;
    const pn_integrator_kind kinds[3] = {PN_INTEGRATOR_REFERENCE, PN_INTEGRATOR_VPL, PN_INTEGRATOR_LIGHTCUTS};
    pn_image img[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
        pn_render_settings s;
        memset(&s, 0, sizeof s);
        s.integrator = kinds[k];
        s.spp = 64;
        s.threads = 2;
        s.aovs = PN_AOV_ILLUMINANCE;
        pn_options o = pn_options_new();
        if (k > 0) pn_options_set(test_context(), o, "vpl-direct-only", "1");
        s.options = o;
        CHECK(pn_render(test_context(), scene, &s, &img[k], NULL) == PN_OK);
        pn_options_free(o);
    }
    if (img[0] && img[1] && img[2]) {
        const float *ref = layer_named(img[0], "illuminance");
        const float *vpl = layer_named(img[1], "illuminance"), *lc = layer_named(img[2], "illuminance");
        CHECK(ref && vpl && lc);
        double sum = 0.0;
        for (int i = 0; ref && vpl && lc && i < 16 * 16; i++) {
            CHECK_NEAR(vpl[i], ref[i], 0.02 * ref[i] + 2.0);
            CHECK_NEAR(lc[i], ref[i], 0.04 * ref[i] + 2.0); /* lightcuts' 2% error bound, and noise */
            sum += ref[i];
        }
        CHECK(sum > 16 * 16 * 50.0); /* the image is lit */
    }
    for (int k = 0; k < 3; k++) pn_image_free(img[k]);
    pn_scene_free(scene);
}

/* ---- glazing --------------------------------------------------------------------------------- */

/* Our own double-precision Fresnel slab transmittance (s and p apart). */
static double slab_t(double ci, double eta) {
    double st2 = (1.0 - ci * ci) / (eta * eta);
    double ct = sqrt(1.0 - st2);
    double rp = pow((eta * ci - ct) / (eta * ci + ct), 2.0), rs = pow((ci - eta * ct) / (ci + eta * ct), 2.0);
    return 0.5 * ((1.0 - rp) / (1.0 + rp) + (1.0 - rs) / (1.0 + rs));
}

static void test_thin_glass_transmittance(void) {
    const char *pane = "AttributeBegin\nMaterial \"thindielectric\" \"float eta\" 1.6\n"
                       "Shape \"trianglemesh\" \"point3 P\" [-8 -8 1  8 -8 1  8 8 1  -8 8 1] "
                       "\"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n";
    char body[2048];
    snprintf(body, sizeof body, "%s%s", point_light, pane);
    pn_scene glass = load_text("glass.pbrt", body);
    snprintf(body, sizeof body, "%s%s", point_light,
             "AttributeBegin\nMaterial \"dielectric\" \"float eta\" 1.6 \"bool thin\" true\n"
             "Shape \"trianglemesh\" \"point3 P\" [-8 -8 1  8 -8 1  8 8 1  -8 8 1] "
             "\"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n");
    pn_scene marked = load_text("glass2.pbrt", body);
    snprintf(body, sizeof body, "%s%s", point_light,
             "AttributeBegin\nMaterial \"dielectric\" \"float eta\" 1.6\n"
             "Shape \"trianglemesh\" \"point3 P\" [-8 -8 1  8 -8 1  8 8 1  -8 8 1] "
             "\"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n");
    pn_scene solid = load_text("glass3.pbrt", body);
    snprintf(body, sizeof body, "%s%s%s", point_light, pane,
             "AttributeBegin\nMaterial \"thindielectric\" \"float eta\" 1.6\n"
             "Shape \"trianglemesh\" \"point3 P\" [-8 -8 1.5  8 -8 1.5  8 8 1.5  -8 8 1.5] "
             "\"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n");
    pn_scene two = load_text("glass4.pbrt", body);
    if (!glass || !marked || !solid || !two) return;
    enum { N = 6 };
    pn_illuminance_point p[N];
    for (int i = 0; i < N; i++) p[i] = up_point(0.4f + 0.7f * (float)i, -0.3f, 0.0f); /* 0 to ~60 degrees */
    double lux[N];
    const char *methods[3] = {"reference", "vpl", "lightcuts"};
    for (int m = 0; m < 3; m++) {
        CHECK(points_lux(glass, methods[m], 1, 2, p, N, lux, NULL, NULL) == PN_OK);
        for (int i = 0; i < N; i++) {
            double e0 = point_closed_form(&p[i]);
            double ci = 2.0 / sqrt(2.0 * 2.0 + pow(0.7 * i, 2.0));
            CHECK_NEAR(lux[i] / e0, slab_t(ci, 1.6), 0.002);
        }
    }
    CHECK(points_lux(marked, "reference", 1, 2, p, N, lux, NULL, NULL) == PN_OK);
    CHECK_NEAR(lux[0] / point_closed_form(&p[0]), slab_t(1.0, 1.6), 0.002);
    CHECK(points_lux(two, "reference", 1, 2, p, N, lux, NULL, NULL) == PN_OK);
    CHECK_NEAR(lux[3] / point_closed_form(&p[3]), pow(slab_t(2.0 / sqrt(4.0 + 4.41), 1.6), 2.0), 0.002);
    /* A solid dielectric stays opaque to shadow rays; opaque-glass makes panes opaque too. */
    CHECK(points_lux(solid, "reference", 1, 2, p, N, lux, NULL, NULL) == PN_OK);
    CHECK(lux[0] == 0.0);
    CHECK(points_lux(glass, "reference", 1, 2, p, N, lux, "opaque-glass", "1") == PN_OK);
    CHECK(lux[0] == 0.0);
    CHECK(points_lux(glass, "vpl", 1, 2, p, N, lux, "opaque-glass", "1") == PN_OK);
    CHECK(lux[0] == 0.0);
    pn_scene_free(glass);
    pn_scene_free(marked);
    pn_scene_free(solid);
    pn_scene_free(two);
}

/* Every integrator passes the pane: the floor under glass against the same floor without it, in
 * the ratio of the transmittance at normal incidence (a point light straight above). */
static void test_thin_glass_every_integrator(void) {
    char body[2048];
    const char *light = "LightSource \"point\" \"point3 from\" [0 0 3] \"rgb I\" [3415 3415 3415]\n";
    snprintf(body, sizeof body, "%s%s", light,
             "AttributeBegin\nMaterial \"thindielectric\" \"float eta\" 1.5\n"
             "Shape \"trianglemesh\" \"point3 P\" [-8 -8 2  8 -8 2  8 8 2  -8 8 2] "
             "\"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n");
    /* The camera below the pane: only shadow rays cross it. */
    const char *saved = header;
    header = "LookAt 0 0 1.5  0 0 0  0 1 0\n"
             "Camera \"orthographic\" \"float screenwindow\" [-2 2 -2 2]\n"
             "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16 \"string filename\" \"x.exr\"\n"
             "WorldBegin\n";
    pn_scene glass = load_text("every.pbrt", body);
    pn_scene open = load_text("every-open.pbrt", light);
    header = saved;
    if (!glass || !open) return;
    const pn_integrator_kind kinds[] = {PN_INTEGRATOR_REFERENCE,  PN_INTEGRATOR_IAS, PN_INTEGRATOR_CONTOUR,
                                        PN_INTEGRATOR_CONTOUR_MC, PN_INTEGRATOR_VPL, PN_INTEGRATOR_LIGHTCUTS,
                                        PN_INTEGRATOR_ILLUMCUT};
    const double expect = slab_t(1.0, 1.5); /* near normal incidence over the small window */
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        pn_render_settings s;
        memset(&s, 0, sizeof s);
        s.integrator = kinds[k];
        s.threads = 2;
        s.spp = kinds[k] == PN_INTEGRATOR_IAS ? 0 : 4;
        pn_options o = pn_options_new();
        if (kinds[k] == PN_INTEGRATOR_VPL || kinds[k] == PN_INTEGRATOR_LIGHTCUTS || kinds[k] == PN_INTEGRATOR_ILLUMCUT)
            pn_options_set(test_context(), o, "vpl-direct-only", "1");
        s.options = o;
        pn_image a = NULL, b = NULL;
        CHECK(pn_render(test_context(), glass, &s, &a, NULL) == PN_OK);
        CHECK(pn_render(test_context(), open, &s, &b, NULL) == PN_OK);
        if (!a || !b) continue;
        const float *pa = pn_image_layer_data(a, 0), *pb = pn_image_layer_data(b, 0);
        double sa = 0, sb = 0;
        for (int i = 0; i < 16 * 16 * 3; i++) sa += pa[i], sb += pb[i];
        CHECK_MSG(fabs(sa / sb / expect - 1.0) < 0.03, "integrator %d: ratio %g, expected %g", (int)kinds[k], sa / sb,
                  expect);
        pn_image_free(a);
        pn_image_free(b);
        pn_options_free(o);
    }
    pn_scene_free(glass);
    pn_scene_free(open);
}

/* ---- the CLI ---------------------------------------------------------------------------------- */

static int run(const char *cmd) {
    int rc = system(cmd);
    return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

static char *slurp(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = malloc((size_t)n + 1);
    size_t got = buf ? fread(buf, 1, (size_t)n, f) : 0;
    fclose(f);
    if (buf) buf[got] = '\0';
    return buf;
}

static void test_cli_csv_json(void) {
    char body[1024];
    snprintf(body, sizeof body, "%s", point_light);
    static char text[4096];
    snprintf(text, sizeof text, "%s%s%s", header, body, floor_quad);
    write_file("cli.pbrt", text);
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s illuminance %s --grid -1.5,-1,1.5,1 --height 0 --spacing 0.4 -o %s --quiet", CLI,
             tpath("cli.pbrt"), tpath("g.csv"));
    CHECK(run(cmd) == 0);
    char *csv = slurp(tpath("g.csv"));
    char *json = slurp(tpath("g.json"));
    FILE *png = fopen(tpath("g.png"), "rb");
    CHECK(csv && json && png);
    if (png) fclose(png);
    if (!csv || !json) return;
    CHECK(strncmp(csv, "x,y,z,nx,ny,nz,illuminance_lux\n", 31) == 0);
    /* ceil(3 / 0.4) = 8 by ceil(2 / 0.4) = 5 cells, a point at each centre */
    int rows = 0;
    double vmin = INFINITY, vmax = 0, sum = 0;
    char *line = strchr(csv, '\n') + 1;
    while (*line) {
        double x, y, z, nx, ny, nz, e;
        CHECK(sscanf(line, "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &x, &y, &z, &nx, &ny, &nz, &e) == 7);
        pn_illuminance_point p = up_point((float)x, (float)y, (float)z);
        CHECK_NEAR(e / point_closed_form(&p), 1.0, 0.005);
        if (rows == 0) CHECK_NEAR(x, -1.5 + 3.0 / 16.0, 1e-6);
        if (rows == 0) CHECK_NEAR(y, -1.0 + 0.2, 1e-6);
        vmin = fmin(vmin, e), vmax = fmax(vmax, e), sum += e;
        rows++;
        line = strchr(line, '\n');
        if (!line) break;
        line++;
    }
    CHECK(rows == 40);
    cJSON *root = cJSON_Parse(json);
    CHECK(root != NULL);
    if (root) {
        CHECK_NEAR(cJSON_GetObjectItem(root, "E_min")->valuedouble, vmin, 1e-4 * vmin);
        CHECK_NEAR(cJSON_GetObjectItem(root, "E_max")->valuedouble, vmax, 1e-4 * vmax);
        CHECK_NEAR(cJSON_GetObjectItem(root, "E_mean")->valuedouble, sum / rows, 1e-4 * vmax);
        CHECK_NEAR(cJSON_GetObjectItem(root, "U0")->valuedouble, vmin / (sum / rows), 1e-4);
        CHECK(cJSON_GetArraySize(cJSON_GetObjectItem(root, "coordinates")) == 40);
        cJSON *grid = cJSON_GetObjectItem(root, "grid");
        CHECK(grid && cJSON_GetObjectItem(grid, "nu")->valueint == 8 && cJSON_GetObjectItem(grid, "nv")->valueint == 5);
        CHECK(strcmp(cJSON_GetObjectItem(root, "quantity")->valuestring, "direct") == 0);
        cJSON_Delete(root);
    }
    free(csv);
    free(json);
}

static void test_cli_daylight_factor(void) {
    static char text[4096];
    snprintf(text, sizeof text, "%s%s%s", header,
             "LightSource \"infinite\" \"string sky\" \"cie-overcast\" \"float illuminance\" 8000\n", floor_quad);
    write_file("df.pbrt", text);
    write_file("df.pts", "# x y z nx ny nz\n0 0 0.001 0 0 1\n\n1.5 -1 0.001 0 0 2\n");
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s illuminance %s --points %s --spp 512 --daylight-factor 8000 -o %s --quiet", CLI,
             tpath("df.pbrt"), tpath("df.pts"), tpath("df.csv"));
    CHECK(run(cmd) == 0);
    char *json = slurp(tpath("df.json"));
    cJSON *root = json ? cJSON_Parse(json) : NULL;
    CHECK(root != NULL);
    if (root) {
        CHECK(cJSON_GetObjectItem(root, "points")->valueint == 2);
        CHECK_NEAR(cJSON_GetObjectItem(root, "DF_mean")->valuedouble, 100.0, 0.5);
        CHECK_NEAR(cJSON_GetObjectItem(root, "DF_min")->valuedouble, 100.0, 0.5);
        cJSON_Delete(root);
    }
    free(json);
}

static void test_cli_bad_point_files(void) {
    static const struct {
        const char *text, *message;
    } cases[] = {
        {"0 0 0 0 0 1\n1 2 3 0 0\n", "bad.pts:2:10: expected 6 numbers (x y z nx ny nz), found 5"},
        {"0 0 0 0 0 1 7\n", "bad.pts:1:13: more than 6 numbers"},
        {"0 0 zero 0 0 1\n", "bad.pts:1:5: 'zero' is not a number"},
        {"0 0 nan 0 0 1\n", "bad.pts:1:5: nan is not a finite coordinate"},
        {"0 0 0 0 0 0\n", "bad.pts:1:1: the normal (0 0 0) has zero length"},
        {"# nothing\n\n", "bad.pts:2:1: no points"},
        {"1e999 0 0 0 0 1\n", "bad.pts:1:1: 1e999 is not a finite coordinate"},
    };
    write_file("ok.pbrt", "WorldBegin\n");
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        write_file("bad.pts", cases[k].text);
        char cmd[2048];
        snprintf(cmd, sizeof cmd, "cd %s && %s illuminance ok.pbrt --points bad.pts -o out%d.csv 2> err.txt",
                 temp_dir(), CLI, (int)k);
        CHECK(run(cmd) == 3);
        char *err = slurp(tpath("err.txt"));
        CHECK_STR_CONTAINS(err, cases[k].message);
        free(err);
        char out[64];
        snprintf(out, sizeof out, "out%d.csv", (int)k);
        FILE *f = fopen(tpath(out), "rb");
        CHECK(f == NULL); /* nothing written */
        if (f) fclose(f);
    }
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "cd %s && %s illuminance ok.pbrt --points missing.pts 2> err.txt", temp_dir(), CLI);
    CHECK(run(cmd) == 3);
    snprintf(cmd, sizeof cmd, "cd %s && %s illuminance ok.pbrt 2> err.txt", temp_dir(), CLI);
    CHECK(run(cmd) == 2);
}

/* ---- false colour ------------------------------------------------------------------------------- */

static void test_false_color_bands_and_log(void) {
    float ramp[64 * 8];
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 64; x++) ramp[y * 64 + x] = (float)(x * 1000.0 / 63.0);
    pn_image img = NULL, fc = NULL;
    CHECK(pn_image_from_values(test_context(), 64, 8, "illuminance", ramp, &img) == PN_OK);
    pn_false_color_options o = {1000.0, 1.0, 0, 5, PN_FALSE_COLOR_BANDS, "lux"};
    CHECK(pn_image_false_color_legend(test_context(), img, "illuminance", &o, &fc) == PN_OK);
    if (!fc) return;
    const int w = pn_image_width(fc);
    const int lw = w - 64;
    CHECK(pn_image_height(fc) >= 128 && lw > 0);
    const float *rgb = pn_image_layer_data(fc, 0);
    /* Bands: the picture's row has exactly 5 colours, changing where x * 1000 / 63 crosses 200 k. */
    int changes = 0;
    for (int x = 1; x < 64; x++) {
        const float *a = rgb + 3 * (size_t)(lw + x - 1), *b = rgb + 3 * (size_t)(lw + x);
        int changed = memcmp(a, b, 12) != 0;
        changes += changed;
        int band_a = (int)((x - 1) * 1000.0 / 63.0 / 200.0), band_b = (int)(x * 1000.0 / 63.0 / 200.0);
        if (band_b > 4) band_b = 4;
        if (band_a > 4) band_a = 4;
        CHECK(changed == (band_a != band_b));
    }
    CHECK(changes == 4);
    /* The legend draws white label pixels. */
    int white = 0;
    for (int y = 0; y < 12; y++)
        for (int x = 0; x < lw; x++)
            white += rgb[3 * ((size_t)y * w + x)] == 1.0f && rgb[3 * ((size_t)y * w + x) + 2] == 1.0f;
    CHECK(white > 5);
    pn_image_free(fc);
    /* Log over 2 decades with 2 divisions: 10 .. 100 is one band, 100 .. 1000 the other. */
    float v[4] = {12.0f, 90.0f, 110.0f, 900.0f};
    pn_image img2 = NULL;
    CHECK(pn_image_from_values(test_context(), 4, 1, "l", v, &img2) == PN_OK);
    pn_false_color_options lo = {1000.0, 1.0, 2, 2, PN_FALSE_COLOR_BANDS, NULL};
    CHECK(pn_image_false_color_legend(test_context(), img2, "l", &lo, &fc) == PN_OK);
    if (fc) {
        const float *q = pn_image_layer_data(fc, 0);
        int l2 = pn_image_width(fc) - 4;
        CHECK(memcmp(q + 3 * (l2 + 0), q + 3 * (l2 + 1), 12) == 0);
        CHECK(memcmp(q + 3 * (l2 + 1), q + 3 * (l2 + 2), 12) != 0);
        CHECK(memcmp(q + 3 * (l2 + 2), q + 3 * (l2 + 3), 12) == 0);
        pn_image_free(fc);
    }
    pn_image_free(img2);
    pn_image_free(img);
}

PN_TESTS(TEST(test_overcast_sky_illuminance), TEST(test_overcast_sky_luminance_profile), TEST(test_sky_bad_input),
         TEST(test_sun_position_published), TEST(test_clear_sky_luminance_and_sun), TEST(test_clear_sky_bad_input),
         TEST(test_grid_point_light_closed_form), TEST(test_grid_matches_illuminance_aov),
         TEST(test_vpl_illuminance_aov_matches_reference), TEST(test_thin_glass_transmittance),
         TEST(test_thin_glass_every_integrator), TEST(test_cli_csv_json), TEST(test_cli_daylight_factor),
         TEST(test_cli_bad_point_files), TEST(test_false_color_bands_and_log))
