/* test_fidelity_scene.c — pbrt-v4's scene-file, film and camera semantics (issue 21, part 2):
 * paths relative to the top-level file, Integrator maxdepth and the VPL depth, warnings with
 * file:line:column, the film's exposure (iso, shutter, white balance, maxcomponentvalue),
 * pixelbounds and reversed crop windows, the orthographic and spherical cameras. Every scene is
 * written by the test into a temporary folder; expected values are closed forms of pbrt-v4's
 * definitions (film.cpp, cameras.cpp, scene.cpp, parser.cpp, util/file.cpp). */
#define _XOPEN_SOURCE 700 /* mkdtemp */
#include "harness.h"

#include "core/context.h"
#include "render/camera.h"
#include "scene/scene.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PN_SCENE_FILES_PREFIX "pn_test_fidelity"
#include "scene_files.h"

/* ---- helpers ----------------------------------------------------------------------------- */

static struct pn_scene_s *parse_text(const char *rel, const char *text, pn_err *err) {
    write_file(rel, text);
    pn_err_init(err);
    struct pn_scene_s *s = NULL;
    pn_scene_parse(test_context(), tpath(rel), &s, err);
    return s;
}

static pn_scene load_text(const char *rel, const char *text) {
    write_file(rel, text);
    pn_scene s = NULL;
    pn_status st = pn_scene_load(test_context(), tpath(rel), &s);
    CHECK_MSG(st == PN_OK, "%s: %s", rel, pn_context_error_message(test_context()));
    return s;
}

static pn_image render(pn_scene s, uint32_t spp) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = PN_INTEGRATOR_REFERENCE;
    rs.spp = spp;
    rs.threads = 2;
    pn_image img = NULL;
    pn_status st = pn_render(test_context(), s, &rs, &img, NULL);
    CHECK_MSG(st == PN_OK, "render: %s", pn_context_error_message(test_context()));
    return img;
}

static const float *pixel(pn_image img, int x, int y) {
    return pn_image_layer_data(img, 0) + 3 * ((size_t)y * (size_t)pn_image_width(img) + (size_t)x);
}

static bool has_warning(struct pn_scene_s *s, const char *needle) {
    for (int i = 0; i < s->warnings.count; i++)
        if (strstr(s->warnings.items[i], needle)) return true;
    return false;
}

/* "PATH:LINE:COLUMN: " with PATH the given file and LINE, COLUMN positive integers. */
static bool starts_with_location(const char *w, const char *path) {
    size_t n = strlen(path);
    if (strncmp(w, path, n) != 0 || w[n] != ':') return false;
    const char *q = w + n + 1;
    for (int field = 0; field < 2; field++) {
        if (!(*q >= '1' && *q <= '9')) return false;
        while (*q >= '0' && *q <= '9') q++;
        if (*q != ':') return false;
        q++;
    }
    return *q == ' ';
}

/* A lit world: a constant environment and, far behind the camera, one small triangle so that
 * the scene has geometry. The camera at the origin looks along +z and sees only the sky. */
#define SKY_WORLD(L)                                                                                                   \
    "WorldBegin\n"                                                                                                     \
    "LightSource \"infinite\" \"rgb L\" [" L "]\n"                                                                     \
    "Shape \"trianglemesh\" \"point3 P\" [0 0 -50 1 0 -50 0 1 -50] \"integer indices\" [0 1 2]\n"

/* ---- 1. relative paths --------------------------------------------------------------------- */

static bool write_pfm_2x1(const char *path) {
    FILE *f = fopen(path, "wb");
    if (!f) return false;
    fprintf(f, "PF\n2 1\n-1.0\n");
    const float px[6] = {0.25f, 0.5f, 0.75f, 1.0f, 0.0f, 0.5f};
    fwrite(px, sizeof px, 1, f);
    fclose(f);
    return true;
}

static void test_paths_resolve_against_top_level_file(void) {
    mkdir(tpath("meshes"), 0700);
    mkdir(tpath("textures"), 0700);
    write_file("meshes/tri.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                 "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                                 "end_header\n0 0 2\n1 0 2\n0 1 2\n3 0 1 2\n");
    CHECK(write_pfm_2x1(tpath("textures/t.pfm")));
    /* Both included files name their files relative to the main file's folder, as pbrt-v4
     * resolves them; nothing exists relative to sub/. */
    write_file("sub/inc.pbrt", "Texture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"textures/t.pfm\"\n"
                               "Material \"diffuse\" \"texture reflectance\" \"t\"\n"
                               "Shape \"plymesh\" \"string filename\" \"meshes/tri.ply\"\n"
                               "Include \"sub/inc2.pbrt\"\n");
    write_file("sub/inc2.pbrt",
               "Shape \"trianglemesh\" \"point3 P\" [0 0 3 1 0 3 0 1 3] \"integer indices\" [0 1 2]\n");
    pn_err err;
    struct pn_scene_s *s = parse_text("paths_main.pbrt", "WorldBegin\nInclude \"sub/inc.pbrt\"\n", &err);
    CHECK_MSG(s != NULL, "%s", err.message);
    if (!s) return;
    CHECK(s->mesh_count == 2 && s->image_count == 1);
    if (s->image_count == 1) CHECK_STR_CONTAINS(s->images[0].path, tpath("textures/t.pfm"));
    if (s->mesh_count == 2) {
        CHECK_NEAR(s->meshes[0].positions[2], 2.0, 1e-6); /* the PLY */
        CHECK_NEAR(s->meshes[1].positions[2], 3.0, 1e-6); /* the nested Include */
        CHECK_STR_CONTAINS(s->meshes[0].source, "sub/inc.pbrt:3:1");
    }
    pn_scene_parse_free(s);

    /* A file that exists only next to the including file is not found, and the error names the
     * path pbrt-v4 would have opened, at the parameter. */
    write_file("sub/only.ply", "ply\n");
    write_file("sub/inc3.pbrt", "Shape \"plymesh\" \"string filename\" \"only.ply\"\n");
    s = parse_text("paths_bad.pbrt", "WorldBegin\nInclude \"sub/inc3.pbrt\"\n", &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    char prefix[600];
    snprintf(prefix, sizeof prefix, "%s:1:17: ", tpath("sub/inc3.pbrt"));
    CHECK_MSG(strncmp(err.message, prefix, strlen(prefix)) == 0, "\"%s\" vs \"%s\"", err.message, prefix);
    CHECK_STR_CONTAINS(err.message, tpath("only.ply"));
    pn_scene_parse_free(s);
}

/* ---- 2. Integrator maxdepth ---------------------------------------------------------------- */

static void test_maxdepth_sets_vpl_depth(void) {
    pn_err err;
    struct pn_scene_s *s =
        parse_text("depth3.pbrt", "Integrator \"path\"\n  \"integer maxdepth\" [ 3 ]\n" SKY_WORLD("1 1 1"), &err);
    CHECK_MSG(s != NULL, "%s", err.message);
    if (s) {
        /* a path of 3 scattering events = the receiving point + a VPL left after 2 bounces */
        CHECK(pn_scene_vpl_depth(s, 10) == 2);
        CHECK(has_warning(s, "depth3.pbrt:2:3: Integrator \"path\" \"maxdepth\" 3"));
        CHECK(has_warning(s, "direct light only"));
        pn_scene_parse_free(s);
    }
    s = parse_text("depth1.pbrt", "Integrator \"path\" \"integer maxdepth\" 1\n" SKY_WORLD("1 1 1"), &err);
    if (s) {
        CHECK(pn_scene_vpl_depth(s, 10) == 0); /* direct light: the light VPLs only */
        CHECK(!has_warning(s, "maxdepth"));
        pn_scene_parse_free(s);
    }
    s = parse_text("depth_none.pbrt", "Integrator \"path\"\n" SKY_WORLD("1 1 1"), &err);
    if (s) {
        CHECK(pn_scene_vpl_depth(s, 10) == 10); /* penumbra's own default when the scene says nothing */
        pn_scene_parse_free(s);
    }
    s = parse_text("depth_neg.pbrt", "Integrator \"path\" \"integer maxdepth\" -2\n" SKY_WORLD("1 1 1"), &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "depth_neg.pbrt:1:19: ");

    /* End to end: the VPL integrator's default depth is the scene's maxdepth - 1, bit for bit. */
    const char *room =
        "Integrator \"path\" \"integer maxdepth\" 4\n"
        "LookAt 0 1 -3  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" 60\n"
        "Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n"
        "WorldBegin\nLightSource \"point\" \"rgb I\" [5 5 5] \"point3 from\" [0 1.8 0]\n"
        "Shape \"trianglemesh\" \"point3 P\" [-2 0 -2 2 0 -2 2 0 2 -2 0 2] \"integer indices\" [0 1 2 0 2 3]\n"
        "Shape \"trianglemesh\" \"point3 P\" [-2 2 -2 -2 2 2 2 2 2 2 2 -2] \"integer indices\" [0 1 2 0 2 3]\n"
        "Shape \"trianglemesh\" \"point3 P\" [-2 0 2 2 0 2 2 2 2 -2 2 2] \"integer indices\" [0 1 2 0 2 3]\n";
    pn_scene sc = load_text("depth_room.pbrt", room);
    if (!sc) return;
    pn_image img[3] = {NULL, NULL, NULL};
    for (int k = 0; k < 3; k++) {
        pn_render_settings rs;
        memset(&rs, 0, sizeof rs);
        rs.integrator = PN_INTEGRATOR_VPL;
        rs.spp = 1;
        rs.threads = 2;
        rs.options = pn_options_new();
        CHECK(pn_options_set_int(test_context(), rs.options, "vpls", 3000) == PN_OK);
        if (k > 0) /* k = 0: vpl-depth not set, the scene's maxdepth decides */
            CHECK(pn_options_set_int(test_context(), rs.options, "vpl-depth", k == 1 ? 3 : 10) == PN_OK);
        CHECK(pn_render(test_context(), sc, &rs, &img[k], NULL) == PN_OK);
        pn_options_free(rs.options);
    }
    if (img[0] && img[1] && img[2]) {
        size_t n = 3 * (size_t)pn_image_width(img[0]) * (size_t)pn_image_height(img[0]);
        CHECK(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[1], 0), n * sizeof(float)) == 0);
        CHECK(memcmp(pn_image_layer_data(img[0], 0), pn_image_layer_data(img[2], 0), n * sizeof(float)) != 0);
    }
    for (int k = 0; k < 3; k++) pn_image_free(img[k]);
    pn_scene_free(sc);
}

/* ---- 3. warnings name file:line:column ----------------------------------------------------- */

static void test_every_warning_has_a_location(void) {
    const char *text = "Sampler \"zsobol\"\n"
                       "  \"integer pixelsamples\" 4\n"
                       "  \"integer seed\" 3\n"
                       "Integrator \"path\"\n"
                       "  \"string lightsampler\" \"bvh\"\n"
                       "Accelerator \"bvh\"\n"
                       "  \"integer maxnodeprims\" 4\n"
                       "PixelFilter \"gaussian\"\n"
                       "  \"float bogus\" 1\n"
                       "Film \"rgb\" \"integer xresolution\" 8 \"integer yresolution\" 8\n"
                       "  \"float diagonal\" 35\n"
                       "Camera \"orthographic\"\n"
                       "  \"float fov\" 45\n"
                       "ColorSpace \"aces2065-1\"\n"
                       "WorldBegin\n"
                       "AttributeBegin\n"
                       "ReverseOrientation\n"
                       "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
                       "Shape \"sphere\" \"float radius\" 0.5 \"float zmax\" 0.2\n"
                       "AttributeEnd\n"
                       "Shape \"trianglemesh\" \"point3 P\" [0 0 2 1 0 2 0 1 2] \"integer indices\" [0 1 2]\n";
    write_file("warn.pbrt", text);
    pn_scene sc = NULL;
    CHECK(pn_scene_load(test_context(), tpath("warn.pbrt"), &sc) == PN_OK);
    if (!sc) return;
    const char *path = tpath("warn.pbrt");
    static const char *const expected[] = {
        ":3:3: unused parameter \"integer seed\" for Sampler \"zsobol\"",
        ":5:3: unused parameter \"string lightsampler\" for Integrator \"path\"",
        ":7:3: unused parameter \"integer maxnodeprims\" for Accelerator \"bvh\"",
        ":9:3: unused parameter \"float bogus\" for PixelFilter \"gaussian\"",
        ":11:3: unused parameter \"float diagonal\" for Film \"rgb\"",
        ":13:3: unused parameter \"float fov\" for Camera \"orthographic\"",
        ":14:12: ColorSpace \"aces2065-1\"",
        ":19:1: partial spheres",
        ":19:1: sphere light 0 emits inwards", /* reported by the light builder, after parsing */
    };
    uint32_t n = pn_scene_warning_count(sc);
    CHECK(n >= sizeof expected / sizeof expected[0]);
    for (uint32_t i = 0; i < n; i++) {
        const char *w = pn_scene_warning(sc, i);
        CHECK_MSG(starts_with_location(w, path), "warning without file:line:column: \"%s\"", w);
    }
    for (size_t k = 0; k < sizeof expected / sizeof expected[0]; k++) {
        char want[700];
        snprintf(want, sizeof want, "%s%s", path, expected[k]);
        bool found = false;
        for (uint32_t i = 0; i < n && !found; i++)
            found = strstr(pn_scene_warning(sc, i), want) == pn_scene_warning(sc, i);
        CHECK_MSG(found, "no warning \"%s\"", want);
    }
    pn_scene_free(sc);
}

/* ---- 4. film and camera exposure ----------------------------------------------------------- */

/* sRGB's RGB_from_XYZ (IEC 61966-2-1), as published. */
static const double srgb_from_xyz[3][3] = {
    {3.2404542, -1.5371385, -0.4985314}, {-0.9692660, 1.8760108, 0.0415560}, {0.0556434, -0.2040259, 1.0572252}};

/* Renders a 4x4 image of the constant sky L under the given Camera directive (or none) and
 * extra Film parameters; every pixel must be the same, which goes to out. */
static void sky_render(const char *rel, const char *camera, const char *film, const char *L, float out[3]) {
    char full[2300];
    snprintf(full, sizeof full,
             "%s\nFilm \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4 %s\nWorldBegin\n"
             "LightSource \"infinite\" \"rgb L\" [%s]\n"
             "Shape \"trianglemesh\" \"point3 P\" [0 0 -50 1 0 -50 0 1 -50] \"integer indices\" [0 1 2]\n",
             camera, film, L);
    out[0] = out[1] = out[2] = NAN;
    pn_scene sc = load_text(rel, full);
    if (!sc) return;
    pn_image img = render(sc, 1);
    if (img) {
        /* the sky is constant: every pixel is the same */
        memcpy(out, pixel(img, 1, 2), 3 * sizeof(float));
        for (int y = 0; y < 4; y++)
            for (int x = 0; x < 4; x++)
                for (int c = 0; c < 3; c++) CHECK(pixel(img, x, y)[c] == out[c]);
    }
    pn_image_free(img);
    pn_scene_free(sc);
}

static void test_iso_and_shutter_scale_the_image(void) {
    float base[3], scaled[3], iso_only[3];
    sky_render("exp_base.pbrt", "", "", "0.5 0.25 0.125", base);
    CHECK_NEAR(base[0], 0.5, 1e-6);
    CHECK_NEAR(base[1], 0.25, 1e-6);
    CHECK_NEAR(base[2], 0.125, 1e-6);
    /* imaging ratio = (shutterclose - shutteropen) * iso / 100 = 0.5 * 400 / 100 = 2 */
    sky_render("exp_scaled.pbrt", "Camera \"perspective\" \"float shutteropen\" 0.25 \"float shutterclose\" 0.75",
               "\"float iso\" 400", "0.5 0.25 0.125", scaled);
    for (int c = 0; c < 3; c++) CHECK_NEAR(scaled[c], 2.0 * (double)base[c], 1e-6 * (double)base[c]);
    sky_render("exp_iso.pbrt", "", "\"float iso\" 50", "0.5 0.25 0.125", iso_only);
    for (int c = 0; c < 3; c++) CHECK_NEAR(iso_only[c], 0.5 * (double)base[c], 1e-6 * (double)base[c]);

    /* pbrt-v4: a shutter that does not open (close <= open, as written) stops the render */
    pn_err err;
    struct pn_scene_s *s =
        parse_text("exp_shut.pbrt",
                   "LookAt 0 0 0 0 0 1 0 1 0\n"
                   "  Camera \"perspective\" \"float shutteropen\" 1 \"float shutterclose\" 0.5\n" SKY_WORLD("1 1 1"),
                   &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "exp_shut.pbrt:2:3: ");
    CHECK_STR_CONTAINS(err.message, "shutter does not open");
    s = parse_text("exp_iso0.pbrt", "Film \"rgb\" \"float iso\" 0\n" SKY_WORLD("1 1 1"), &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "exp_iso0.pbrt:1:12: ");
}

/* The CIE daylight locus at the temperature pbrt-v4 uses (T * 1.4388 / 1.4380). */
static void daylight_xy(double kelvin, double *x, double *y) {
    double T = kelvin * 1.4388 / 1.4380, t = 1e3 / T;
    *x = T <= 7000.0 ? -4.6070 * t * t * t + 2.9678 * t * t + 0.09911 * t + 0.244063
                     : -2.0064 * t * t * t + 1.9018 * t * t + 0.24748 * t + 0.237040;
    *y = -3.0 * *x * *x + 2.870 * *x - 0.275;
}

static void test_white_balance_and_max_component(void) {
    /* A sky whose colour is the daylight white of 5000 K (luminance 1) comes out neutral, (1 1 1)
     * in sRGB, once white-balanced for 5000 K: the von Kries transform maps the source white
     * onto D65, which is sRGB's (1, 1, 1). */
    double x, y;
    daylight_xy(5000.0, &x, &y);
    double xyz[3] = {x / y, 1.0, (1.0 - x - y) / y}, rgb[3];
    for (int r = 0; r < 3; r++)
        rgb[r] = srgb_from_xyz[r][0] * xyz[0] + srgb_from_xyz[r][1] * xyz[1] + srgb_from_xyz[r][2] * xyz[2];
    char L[128];
    snprintf(L, sizeof L, "%.9f %.9f %.9f", rgb[0], rgb[1], rgb[2]);
    float plain[3], balanced[3];
    sky_render("wb_plain.pbrt", "", "", L, plain);
    for (int c = 0; c < 3; c++) CHECK_NEAR(plain[c], rgb[c], 1e-6);
    CHECK(fabsf(plain[0] - plain[2]) > 0.1f); /* visibly warm before */
    sky_render("wb_5000.pbrt", "", "\"float whitebalance\" 5000", L, balanced);
    /* (the published matrix above is for a D65 white 1e-4 away from the xy (0.3127, 0.3290)
     * that pbrt's and penumbra's sRGB are built on, hence the tolerance) */
    for (int c = 0; c < 3; c++) CHECK_NEAR(balanced[c], 1.0, 5e-4);

    /* maxcomponentvalue clamps the sensor value: with the cie1931 sensor that is XYZ times the
     * imaging ratio, scaled down until its largest component (Z for a grey) equals the bound. */
    float clamped[3];
    sky_render("maxc.pbrt", "", "\"float maxcomponentvalue\" 1", "2 2 2", clamped);
    /* Z of sRGB's white (1 1 1), from its xy (0.3127, 0.3290) at Y = 1 */
    double zsum = (1.0 - 0.3127 - 0.3290) / 0.3290;
    for (int c = 0; c < 3; c++) CHECK_NEAR(clamped[c], 1.0 / zsum, 1e-5);
    float below[3];
    sky_render("maxc_below.pbrt", "", "\"float maxcomponentvalue\" 10", "2 2 2", below);
    for (int c = 0; c < 3; c++) CHECK_NEAR(below[c], 2.0, 1e-5);

    /* a named sensor: warned, the XYZ response is kept and pbrt's 6500 K default applied */
    pn_err err;
    struct pn_scene_s *s =
        parse_text("sensor.pbrt", "Film \"rgb\" \"string sensor\" \"canon_eos_100d\"\n" SKY_WORLD("1 1 1"), &err);
    CHECK(s != NULL);
    if (s) {
        CHECK(has_warning(s, "sensor.pbrt:1:12: \"sensor\" \"canon_eos_100d\" is not supported"));
        CHECK_NEAR(s->camera.white_balance_k, 6500.0, 1e-3);
        pn_scene_parse_free(s);
    }
}

/* ---- 4b. pixelbounds and reversed crop windows --------------------------------------------- */

#define LIT_WORLD                                                                                                      \
    "LookAt 0 0 -4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 50\n"                                           \
    "WorldBegin\nLightSource \"point\" \"rgb I\" [4 4 4] \"point3 from\" [1 2 -3]\n"                                   \
    "Shape \"sphere\" \"float radius\" 1\n"                                                                            \
    "Shape \"trianglemesh\" \"point3 P\" [-3 -1 -3 3 -1 -3 3 -1 3 -3 -1 3] \"integer indices\" [0 1 2 0 2 3]\n"

static pn_image render_film(const char *rel, const char *film) {
    char text[2048];
    snprintf(text, sizeof text, "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 12 %s\n" LIT_WORLD,
             film);
    pn_scene sc = load_text(rel, text);
    if (!sc) return NULL;
    pn_image img = render(sc, 2);
    pn_scene_free(sc);
    return img;
}

/* The window image equals the full image's pixels at offset (x0, y0), bit for bit. */
static void check_window(pn_image full, pn_image win, int x0, int y0, int w, int h) {
    CHECK(win != NULL);
    if (!full || !win) return;
    CHECK(pn_image_width(win) == w && pn_image_height(win) == h);
    if (pn_image_width(win) != w || pn_image_height(win) != h) return;
    int differ = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            differ += memcmp(pixel(win, x, y), pixel(full, x0 + x, y0 + y), 3 * sizeof(float)) != 0;
    CHECK_MSG(differ == 0, "%d pixels differ from the full image", differ);
}

static void test_pixelbounds_and_reversed_cropwindow(void) {
    pn_image full = render_film("pb_full.pbrt", "");
    CHECK(full && pn_image_width(full) == 16 && pn_image_height(full) == 12);
    /* pixelbounds [x0 x1 y0 y1]: the integer window [3, 11) x [2, 7) */
    pn_image pb = render_film("pb.pbrt", "\"integer pixelbounds\" [3 11 2 7]");
    check_window(full, pb, 3, 2, 8, 5);
    pn_image_free(pb);
    /* pbrt takes the bounds of the two corners: a reversed pair is the same window */
    pb = render_film("pb_rev.pbrt", "\"integer pixelbounds\" [11 3 7 2]");
    check_window(full, pb, 3, 2, 8, 5);
    pn_image_free(pb);
    /* beyond the film: clamped, with a warning */
    pb = render_film("pb_clamp.pbrt", "\"integer pixelbounds\" [-2 4 0 20]");
    check_window(full, pb, 0, 0, 4, 12);
    pn_image_free(pb);
    /* the crop window, sorted and clamped per axis as pbrt does: [0.25, 0.75] x [0, 0.5] */
    pn_image cw = render_film("cw_rev.pbrt", "\"float cropwindow\" [0.75 0.25 0.5 -0.5]");
    check_window(full, cw, 4, 0, 8, 6);
    pn_image_free(cw);
    /* both given: the crop window wins (pbrt), with a warning at the pixel bounds */
    pn_err err;
    struct pn_scene_s *s =
        parse_text("pb_both.pbrt",
                   "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 12\n"
                   "  \"float cropwindow\" [0 0.5 0 0.5] \"integer pixelbounds\" [0 2 0 2]\n" LIT_WORLD,
                   &err);
    CHECK(s != NULL);
    if (s) {
        CHECK(!s->camera.pixel_bounds_given && s->camera.crop[1] == 0.5f);
        CHECK(has_warning(s, "pb_both.pbrt:2:36: both \"pixelbounds\" and \"cropwindow\""));
        pn_scene_parse_free(s);
    }
    s = parse_text("pb_clamp_w.pbrt",
                   "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 12 \"integer pixelbounds\" [-2 4 0 "
                   "20]\n" LIT_WORLD,
                   &err);
    if (s) {
        CHECK(has_warning(s, "pb_clamp_w.pbrt:1:62: \"pixelbounds\" extends beyond the 16x12 film"));
        pn_scene_parse_free(s);
    }
    /* empty windows are errors at the parameter */
    s = parse_text("pb_empty.pbrt",
                   "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 12 \"integer pixelbounds\" [3 3 0 "
                   "5]\n" LIT_WORLD,
                   &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "pb_empty.pbrt:1:62: \"pixelbounds\" [3 3 0 5] covers no pixel");
    s = parse_text("cw_empty.pbrt",
                   "Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 12 \"float cropwindow\" [0.51 0.55 "
                   "0 1]\n" LIT_WORLD,
                   &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "cw_empty.pbrt:1:62: \"cropwindow\"");
    pn_image_free(full);
}

/* ---- 5. cameras ------------------------------------------------------------------------------ */

static bool camera_of(const char *rel, const char *text, pn_camera *cam, struct pn_scene_s **keep) {
    pn_err err;
    struct pn_scene_s *s = parse_text(rel, text, &err);
    CHECK_MSG(s != NULL, "%s", err.message);
    *keep = s;
    if (!s) return false;
    const float crop[4] = {0, 1, 0, 1};
    return pn_camera_setup(&s->camera, s->camera.width, s->camera.height, crop, cam);
}

static void check_vec(vec3 a, double x, double y, double z, double tol) {
    CHECK_MSG(fabs((double)a.x - x) <= tol && fabs((double)a.y - y) <= tol && fabs((double)a.z - z) <= tol,
              "(%g %g %g) vs (%g %g %g)", (double)a.x, (double)a.y, (double)a.z, x, y, z);
}

static void test_orthographic_camera_rays(void) {
    pn_camera cam;
    struct pn_scene_s *s;
    /* camera_from_world = translate(0 0 5): the camera sits at z = -5 of the world */
    bool ok = camera_of("ortho.pbrt",
                        "Translate 0 0 5\nCamera \"orthographic\" \"float screenwindow\" [-2 2 -1 1]\n"
                        "Film \"rgb\" \"integer xresolution\" 40 \"integer yresolution\" 20\n" SKY_WORLD("1 1 1"),
                        &cam, &s);
    CHECK(ok);
    if (ok) {
        vec3 o, d;
        /* raster (0, 0) is the screen window's top-left corner (-2, 1) */
        pn_camera_ray(&cam, 0.0f, 0.0f, 0.5f, 0.5f, &o, &d);
        check_vec(o, -2, 1, -5, 1e-5);
        check_vec(d, 0, 0, 1, 1e-6);
        pn_camera_ray(&cam, 40.0f, 20.0f, 0.5f, 0.5f, &o, &d);
        check_vec(o, 2, -1, -5, 1e-5);
        pn_camera_ray(&cam, 30.0f, 5.0f, 0.1f, 0.9f, &o, &d);
        check_vec(o, 1, 0.5, -5, 1e-5);
        check_vec(d, 0, 0, 1, 1e-6);
    }
    pn_scene_parse_free(s);
    /* default screen window from the aspect ratio (2:1 -> [-2 2] x [-1 1]) and a thin lens: pbrt
     * starts the ray on the lens around the axis and aims it at the screen point at depth 4 */
    ok = camera_of("ortho_lens.pbrt",
                   "Camera \"orthographic\" \"float lensradius\" 0.5 \"float focaldistance\" 4\n"
                   "Film \"rgb\" \"integer xresolution\" 40 \"integer yresolution\" 20\n" SKY_WORLD("1 1 1"),
                   &cam, &s);
    CHECK(ok);
    if (ok) {
        vec3 o, d;
        pn_camera_ray(&cam, 0.0f, 0.0f, 0.5f, 0.5f, &o, &d); /* the lens centre */
        check_vec(o, 0, 0, 0, 1e-6);
        double n = sqrt(4.0 + 1.0 + 16.0);
        check_vec(d, -2 / n, 1 / n, 4 / n, 1e-5);
        pn_camera_ray(&cam, 20.0f, 10.0f, 1.0f, 0.5f, &o, &d); /* lens point (0.5, 0) */
        check_vec(o, 0.5, 0, 0, 1e-6);
        n = sqrt(0.25 + 16.0);
        check_vec(d, -0.5 / n, 0, 4 / n, 1e-5);
    }
    pn_scene_parse_free(s);
    /* End to end: a diffuse wall (kd 0.5) at x >= 1 lit head-on by a distant light of
     * irradiance 1. Through the orthographic camera its edge is the screen's x = 1, raster
     * column 30 of 40, whatever its depth; its radiance is kd / pi. */
    for (int depth = 3; depth <= 30; depth *= 10) {
        char text[1024];
        snprintf(
            text, sizeof text,
            "Camera \"orthographic\" \"float screenwindow\" [-2 2 -1 1]\n"
            "Film \"rgb\" \"integer xresolution\" 40 \"integer yresolution\" 20\n"
            "PixelFilter \"box\"\nWorldBegin\n"
            "LightSource \"distant\" \"point3 from\" [0 0 0] \"point3 to\" [0 0 1] \"rgb L\" [1 1 1]\n"
            "Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n"
            "Shape \"trianglemesh\" \"point3 P\" [1 -5 %d 9 -5 %d 9 5 %d 1 5 %d] \"integer indices\" [0 1 2 0 2 3]\n",
            depth, depth, depth, depth);
        char rel[64];
        snprintf(rel, sizeof rel, "ortho_wall_%d.pbrt", depth);
        pn_scene sc = load_text(rel, text);
        if (!sc) continue;
        pn_image img = render(sc, 4);
        if (img) {
            int wrong = 0;
            for (int y = 0; y < 20; y++)
                for (int x = 0; x < 40; x++) {
                    double v = (double)pixel(img, x, y)[1], want = x < 30 ? 0.0 : 0.5 / M_PI;
                    wrong += fabs(v - want) > 1e-4;
                }
            CHECK_MSG(wrong == 0, "depth %d: %d pixels differ from the orthographic closed form", depth, wrong);
        }
        pn_image_free(img);
        pn_scene_free(sc);
    }
    /* a sky render through the orthographic camera sees the sky everywhere */
    float sky[3];
    sky_render("ortho_sky.pbrt", "Camera \"orthographic\"", "", "0.5 0.5 0.5", sky);
    CHECK_NEAR(sky[1], 0.5, 1e-6);
}

static void test_spherical_camera_rays(void) {
    pn_camera cam;
    struct pn_scene_s *s;
    bool ok = camera_of("equirect.pbrt",
                        "Camera \"spherical\" \"string mapping\" \"equirectangular\"\n"
                        "Film \"rgb\" \"integer xresolution\" 64 \"integer yresolution\" 32\n" SKY_WORLD("1 1 1"),
                        &cam, &s);
    CHECK(ok);
    if (ok) {
        vec3 o, d;
        /* theta = pi v, phi = 2 pi u; direction (sin t cos p, cos t, sin t sin p) after pbrt's
         * y/z swap: the top row looks up, u = 1/4 of the row through the middle looks along +z */
        pn_camera_ray(&cam, 16.0f, 16.0f, 0.5f, 0.5f, &o, &d);
        check_vec(o, 0, 0, 0, 1e-6);
        check_vec(d, 0, 0, 1, 1e-6);
        pn_camera_ray(&cam, 0.0f, 16.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 1, 0, 0, 1e-6);
        pn_camera_ray(&cam, 48.0f, 16.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 0, 0, -1, 1e-6);
        pn_camera_ray(&cam, 5.0f, 0.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 0, 1, 0, 1e-6);
        /* a general pixel: u = 0.3, v = 0.2 */
        double t = M_PI * 0.2, p = 2 * M_PI * 0.3;
        pn_camera_ray(&cam, 0.3f * 64.0f, 0.2f * 32.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, sin(t) * cos(p), cos(t), sin(t) * sin(p), 1e-5);
    }
    pn_scene_parse_free(s);

    ok = camera_of("equalarea.pbrt",
                   "Camera \"spherical\"\n"
                   "Film \"rgb\" \"integer xresolution\" 32 \"integer yresolution\" 32\n" SKY_WORLD("1 1 1"),
                   &cam, &s);
    CHECK(ok);
    if (ok) {
        vec3 o, d;
        /* the default mapping is equal-area: the square's centre is the octahedron's +z pole
         * (camera up after the swap), its corners -z, the middle of its right edge +x */
        pn_camera_ray(&cam, 16.0f, 16.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 0, 1, 0, 1e-6);
        pn_camera_ray(&cam, 0.0f, 0.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 0, -1, 0, 1e-6);
        pn_camera_ray(&cam, 32.0f, 16.0f, 0.5f, 0.5f, &o, &d);
        check_vec(d, 1, 0, 0, 1e-6);
        /* equal area: a uniform grid over the square gives uniform directions, so the mean of
         * each component is 0 and the mean of its square 1/3 (grid error well below 1e-3) */
        double sum[3] = {0, 0, 0}, sq[3] = {0, 0, 0};
        const int N = 256;
        for (int j = 0; j < N; j++)
            for (int i = 0; i < N; i++) {
                pn_camera_ray(&cam, 32.0f * ((float)i + 0.5f) / N, 32.0f * ((float)j + 0.5f) / N, 0.5f, 0.5f, &o, &d);
                double c[3] = {d.x, d.y, d.z};
                for (int k = 0; k < 3; k++) {
                    sum[k] += c[k];
                    sq[k] += c[k] * c[k];
                }
            }
        for (int k = 0; k < 3; k++) {
            CHECK_NEAR(sum[k] / (N * N), 0.0, 1e-3);
            CHECK_NEAR(sq[k] / (N * N), 1.0 / 3.0, 1e-3);
        }
    }
    pn_scene_parse_free(s);

    pn_err err;
    s = parse_text("sph_bad.pbrt", "Camera \"spherical\" \"string mapping\" \"equirect\"\n" SKY_WORLD("1 1 1"), &err);
    CHECK(s == NULL && err.status == PN_ERROR_BAD_INPUT);
    CHECK_STR_CONTAINS(err.message, "sph_bad.pbrt:1:20: unknown \"mapping\" \"equirect\"");
    s = parse_text("realistic.pbrt", "Camera \"realistic\" \"string lensfile\" \"wide.dat\"\n" SKY_WORLD("1 1 1"),
                   &err);
    CHECK(s == NULL && err.status == PN_ERROR_UNSUPPORTED);
    CHECK_STR_CONTAINS(err.message, "realistic.pbrt:1:8: Camera \"realistic\"");
    CHECK_STR_CONTAINS(err.message, "use Camera \"perspective\" with \"lensradius\" and \"focaldistance\"");
}

/* Sphere (u, v) are pbrt-v4's, in object space: v = 1 - theta / pi (0 at the object's -z pole),
 * so a checkerboard of one cell in u and two in v (0.2 below the object's equator, 0.8 above),
 * lit from the camera, is four times brighter in the image's upper half than in its lower; the
 * sphere rotated 90 degrees about x carries the boundary with it (left and right halves differ,
 * upper and lower do not). Before: v = theta / pi in world space (the halves swapped, and the
 * rotated sphere's boundary stayed horizontal). */
static void sphere_halves(const char *rel, const char *rotate, double *top_bottom, double *left_right) {
    char text[2048];
    snprintf(text, sizeof text,
             "LookAt 6 0 0  0 0 0  0 0 1\n"
             "Camera \"orthographic\" \"float screenwindow\" [ -1.2 1.2 -1.2 1.2 ]\n"
             "Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n"
             "WorldBegin\n"
             "LightSource \"distant\" \"point3 from\" [ 1 0 0 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 1 1 1 ]\n"
             "Texture \"c\" \"spectrum\" \"checkerboard\" \"float uscale\" 1 \"float vscale\" 2\n"
             "   \"rgb tex1\" [ 0.2 0.2 0.2 ] \"rgb tex2\" [ 0.8 0.8 0.8 ]\n"
             "Material \"diffuse\" \"texture reflectance\" \"c\"\n"
             "AttributeBegin\n%s\nShape \"sphere\" \"float radius\" 1\nAttributeEnd\n",
             rotate);
    pn_scene sc = load_text(rel, text);
    pn_image img = sc ? render(sc, 4) : NULL;
    *top_bottom = *left_right = 0.0;
    if (img) {
        double half[4] = {0, 0, 0, 0}; /* top, bottom, left, right */
        for (int y = 0; y < 32; y++)
            for (int x = 0; x < 32; x++) {
                double v = pixel(img, x, y)[1];
                half[y < 16 ? 0 : 1] += v;
                half[x < 16 ? 2 : 3] += v;
            }
        *top_bottom = half[0] / half[1];
        *left_right = half[2] > half[3] ? half[2] / half[3] : half[3] / half[2];
    }
    pn_image_free(img);
    pn_scene_free(sc);
}

static void test_sphere_uv_object_space(void) {
    double tb, lr;
    sphere_halves("sphere_uv.pbrt", "", &tb, &lr);
    CHECK_MSG(fabs(tb - 4.0) < 0.4 && fabs(lr - 1.0) < 0.05, "upright: top / bottom %.3f, left / right %.3f", tb, lr);
    sphere_halves("sphere_uv_rot.pbrt", "Rotate 90 1 0 0", &tb, &lr);
    CHECK_MSG(fabs(tb - 1.0) < 0.05 && fabs(lr - 4.0) < 0.4, "rotated: top / bottom %.3f, left / right %.3f", tb, lr);
}

PN_TESTS(TEST(test_paths_resolve_against_top_level_file), TEST(test_maxdepth_sets_vpl_depth),
         TEST(test_every_warning_has_a_location), TEST(test_iso_and_shutter_scale_the_image),
         TEST(test_white_balance_and_max_component), TEST(test_pixelbounds_and_reversed_cropwindow),
         TEST(test_orthographic_camera_rays), TEST(test_spherical_camera_rays), TEST(test_sphere_uv_object_space))
