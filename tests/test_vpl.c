/* test_vpl.c — VPL tracing and the all-VPL reference: eq. 1 of IlluminationCut against a formula
 * written out here for random configurations (omni, spot-free point, oriented and directional
 * VPLs, Lambert and normalised Blinn-Phong receivers, clamping); determinism of the VPL set for a
 * seed; the first bounce's energy against the closed-form flux a point light sends onto a
 * square; the vpl integrator's image against the closed-form direct light of a point light over
 * a plane; its image against a brute-force sum over the VPLs computed here; CLI bad values. */
#include "harness.h"

#include "core/rng.h"
#include "lights/vpl.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"
#include "vpl_scenes.h"

#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static vec3 rand_dir(pn_rng *rng) {
    for (;;) {
        vec3 v = v3(2.0f * pn_rng_float(rng) - 1.0f, 2.0f * pn_rng_float(rng) - 1.0f, 2.0f * pn_rng_float(rng) - 1.0f);
        float l = v3_length(v);
        if (l > 0.05f && l <= 1.0f) return v3_scale(v, 1.0f / l);
    }
}

/* eq. 1 for one channel, written independently of vpl.c: Lambert k_d / pi cos theta plus
 * k_s (n + 2) / (2 pi) cos^n beta cos theta, beta between the mirrored view direction and the
 * light; G = cos phi / max(d^2, d_min^2) (oriented), 1 / max(d^2, d_min^2) (omni), 1
 * (directional). */
typedef struct dvec {
    double x, y, z;
} dvec;
static dvec D(vec3 v) {
    return (dvec){(double)v.x, (double)v.y, (double)v.z};
}
static double ddot(dvec a, dvec b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

static double eq1(const pn_vpl *v, vec3 pf, vec3 nf, vec3 wof, double kd, double ks, double e, double I, double dmin2) {
    dvec p = D(pf), n = D(nf), wo = D(wof), vp = D(v->p), vn = D(v->n), l;
    double G;
    if (v->kind == PN_VPL_DIRECTIONAL) {
        l = vp;
        G = 1.0;
    } else {
        dvec d = {vp.x - p.x, vp.y - p.y, vp.z - p.z};
        double d2 = ddot(d, d), len = sqrt(d2);
        l = (dvec){d.x / len, d.y / len, d.z / len};
        G = 1.0 / (d2 > dmin2 ? d2 : dmin2);
        if (v->kind == PN_VPL_ORIENTED) {
            double cphi = -ddot(vn, l);
            if (cphi <= 0.0) return 0.0;
            G *= cphi;
        }
    }
    double ct = ddot(n, l);
    if (ct <= 0.0) return 0.0;
    double wn = ddot(wo, n);
    dvec r = {2.0 * wn * n.x - wo.x, 2.0 * wn * n.y - wo.y, 2.0 * wn * n.z - wo.z};
    double cb = ddot(r, l);
    double M = kd / M_PI + (cb > 0.0 ? ks * (e + 2.0) / (2.0 * M_PI) * pow(cb, e) : 0.0);
    return M * ct * G * I;
}

static void test_contribution_is_eq1(void) {
    pn_rng rng;
    pn_rng_seed(&rng, 5, 1);
    pn_lights lights;
    memset(&lights, 0, sizeof lights);
    int nonzero = 0;
    for (int i = 0; i < 20000; i++) {
        pn_vpl v;
        memset(&v, 0, sizeof v);
        v.kind = (int32_t)(i % 3);
        v.light = -1;
        v.p = v.kind == PN_VPL_DIRECTIONAL
                  ? rand_dir(&rng)
                  : v3(4 * pn_rng_float(&rng) - 2, 4 * pn_rng_float(&rng) - 2, 4 * pn_rng_float(&rng) - 2);
        v.n = v.kind == PN_VPL_ORIENTED ? rand_dir(&rng) : v3(0, 0, 0);
        v.intensity = v3(pn_rng_float(&rng), 2 * pn_rng_float(&rng), 0.5f);
        pn_vpl_receiver r;
        r.p = v3(pn_rng_float(&rng), pn_rng_float(&rng), pn_rng_float(&rng));
        r.ns = r.ng = rand_dir(&rng);
        r.wo = rand_dir(&rng);
        if (v3_dot(r.wo, r.ns) < 0.0f) r.wo = v3_neg(r.wo);
        r.kd = v3(0.3f, 0.6f, 0.9f);
        r.ks = (i % 2) ? v3(0.2f, 0.1f, 0.4f) : v3(0, 0, 0);
        r.exponent = 1.0f + 100.0f * pn_rng_float(&rng);
        r = pn_vpl_receiver_rgb(r.p, r.ng, r.ns, r.wo, r.kd, r.ks, r.exponent);
        float dmin2 = (i % 4 == 0) ? 0.0f : 0.3f;
        vec3 wi;
        float dist;
        vec3 c = pn_vpl_contribution(&lights, &v, &r, dmin2, &wi, &dist);
        double ex = eq1(&v, r.p, r.ns, r.wo, (double)r.kd.x, (double)r.ks.x, (double)r.exponent, (double)v.intensity.x,
                        (double)dmin2);
        double ey = eq1(&v, r.p, r.ns, r.wo, (double)r.kd.y, (double)r.ks.y, (double)r.exponent, (double)v.intensity.y,
                        (double)dmin2);
        CHECK_NEAR(c.x, ex, 1e-4 * (1.0 + ex));
        CHECK_NEAR(c.y, ey, 1e-4 * (1.0 + ey));
        if (ex > 0.0) nonzero++;
    }
    CHECK(nonzero > 3000);
}

static void test_trace_is_deterministic(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room.pbrt", pn_test_room_scene(0, 8, 8));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_vpl_settings s = {5000, 10, 0.05f, 7};
    pn_vpl_set a, b, c;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &a, &err) == PN_OK);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &b, &err) == PN_OK);
    s.seed = 8;
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &c, &err) == PN_OK);
    CHECK(a.count >= 4990 && a.count <= 5010);
    CHECK(a.count == b.count && memcmp(a.vpls, b.vpls, a.count * sizeof *a.vpls) == 0);
    CHECK(a.count != c.count || memcmp(a.vpls, c.vpls, a.count * sizeof *a.vpls) != 0);
    /* The point light is one exact omni VPL; the rest are oriented (area light + bounces). */
    CHECK(a.count_by_kind[PN_VPL_OMNI] == 1 && a.count_by_kind[PN_VPL_DIRECTIONAL] == 0);
    CHECK_NEAR(a.clamp_distance, 0.05 * (double)scene->lights->scene_radius, 1e-6);
    pn_vpl_set_free(&a);
    pn_vpl_set_free(&b);
    pn_vpl_set_free(&c);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A point light of intensity I at height h over a square floor of half-side A (reflectance kd),
 * nothing else: the first-bounce VPLs together re-emit kd times the flux the square receives,
 * kd I Omega with Omega = 4 asin(A^2 / (A^2 + h^2)); a Lambertian VPL of intensity I_v emits
 * pi I_v. */
static void test_first_bounce_energy(void) {
    pn_context ctx = pn_context_new();
    const double I = 2.0, h = 1.0, A = 3.0, kd = 0.5;
    char text[1024];
    snprintf(text, sizeof text,
             "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 30 ]\n"
             "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\nWorldBegin\n"
             "Material \"diffuse\" \"rgb reflectance\" [ %g %g %g ]\n"
             "Shape \"trianglemesh\" \"point3 P\" [ -%g -%g 0  %g -%g 0  %g %g 0  -%g %g 0 ] \"integer indices\" [ 0 1 "
             "2  0 2 3 ]\n"
             "LightSource \"point\" \"point3 from\" [ 0 0 %g ] \"rgb I\" [ %g %g %g ]\n",
             kd, kd, kd, A, A, A, A, A, A, A, A, h, I, I, I);
    pn_scene scene = vpl_test_load(ctx, "floor.pbrt", text);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_vpl_settings s = {40001, 1, 0.05f, 3};
    pn_vpl_set set;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &set, &err) == PN_OK);
    double sum = 0.0;
    for (uint32_t i = 0; i < set.count; i++)
        if (set.vpls[i].kind == PN_VPL_ORIENTED) sum += M_PI * (double)set.vpls[i].intensity.x;
    double omega = 4.0 * asin(A * A / (A * A + h * h));
    double expected = kd * I * omega;
    /* Binomial: hit probability p = omega / 4 pi over ~40000 / p paths; 5 sigma. */
    double p = omega / (4.0 * M_PI);
    double rel_sigma = sqrt((1.0 - p) / 40000.0);
    CHECK_MSG(fabs(sum - expected) <= 5.0 * rel_sigma * expected, "sum %g expected %g", sum, expected);
    pn_vpl_set_free(&set);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* The vpl integrator over a plane lit by a point light right above the image centre: no
 * indirect light (a plane does not see itself), so each pixel is kd / pi I h / d^3 averaged over
 * the pixel. The image is symmetric about the centre, so the raster-to-plane mapping needs no
 * orientation convention. */
static void test_vpl_image_closed_form(void) {
    pn_context ctx = pn_context_new();
    const double I = 3.0, h = 2.0, H = 5.0, kd = 0.6, fov = 30.0;
    const int W = 16;
    char text[1024];
    snprintf(text, sizeof text,
             "LookAt 0 0 %g  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ %g ]\n"
             "Film \"rgb\" \"integer xresolution\" [ %d ] \"integer yresolution\" [ %d ]\nWorldBegin\n"
             "Material \"diffuse\" \"rgb reflectance\" [ %g %g %g ]\n"
             "Shape \"trianglemesh\" \"point3 P\" [ -50 -50 0  50 -50 0  50 50 0  -50 50 0 ] \"integer indices\" [ 0 1 "
             "2  0 2 3 ]\n"
             "LightSource \"point\" \"point3 from\" [ 0 0 %g ] \"rgb I\" [ %g %g %g ]\n",
             H, fov, W, W, kd, kd, kd, h, I, I, I);
    pn_scene scene = vpl_test_load(ctx, "plane.pbrt", text);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    pn_options o = pn_options_new();
    rs.options = o;
    rs.integrator = PN_INTEGRATOR_VPL;
    pn_options_set_int(ctx, o, "vpls", 300);
    pn_options_set_double(ctx, o, "vpl-clamp", (double)1e-4f);
    rs.spp = 16;
    rs.threads = 2;
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    pn_options_free(o);
    if (img) {
        const float *px = pn_image_layer_data(img, 0);
        double t = tan(fov * M_PI / 360.0), worst = 0.0;
        for (int y = 0; y < W; y++)
            for (int x = 0; x < W; x++) {
                /* Mean over the pixel footprint of the closed form (5x5 points). */
                double mean = 0.0;
                for (int a = 0; a < 5; a++)
                    for (int b = 0; b < 5; b++) {
                        double sx = (2.0 * (x + (a + 0.5) / 5.0) / W - 1.0) * t * H;
                        double sy = (2.0 * (y + (b + 0.5) / 5.0) / W - 1.0) * t * H;
                        double d2 = sx * sx + sy * sy + h * h;
                        mean += kd / M_PI * I * h / (d2 * sqrt(d2)) / 25.0;
                    }
                double v = (double)px[3 * (y * W + x)];
                double rel = fabs(v - mean) / mean;
                if (rel > worst) worst = rel;
            }
        CHECK_MSG(worst < 0.015, "worst relative error %g", worst);
    }
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A scene with no light renders black, without error. */
static void test_no_lights(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene =
        vpl_test_load(ctx, "dark.pbrt",
                      "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 30 ]\n"
                      "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\nWorldBegin\n"
                      "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ] \"integer indices\" [ 0 "
                      "1 2  0 2 3 ]\n");
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_integrator_kind kinds[3] = {PN_INTEGRATOR_VPL, PN_INTEGRATOR_LIGHTCUTS, PN_INTEGRATOR_ILLUMCUT};
    for (int k = 0; k < 3; k++) {
        pn_render_settings rs;
        memset(&rs, 0, sizeof rs);
        pn_options o = pn_options_new();
        rs.options = o;
        rs.integrator = kinds[k];
        pn_options_set_int(ctx, o, "vpls", 100);
        pn_image img = NULL;
        CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
        pn_options_free(o);
        if (img) {
            const float *px = pn_image_layer_data(img, 0);
            double sum = 0.0;
            for (int i = 0; i < 8 * 8 * 3; i++) sum += (double)px[i];
            CHECK(sum == 0.0);
        }
        pn_image_free(img);
    }
    /* Out-of-range settings are refused with a message, not clamped. */
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = PN_INTEGRATOR_LIGHTCUTS;
    pn_options o = pn_options_new();
    rs.options = o;
    /* Refused where it is set, against the declared range of the option. */
    CHECK(pn_options_set_double(ctx, o, "error", (double)1.5f) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "error bound");
    pn_options_free(o);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static int run_cli(const char *args, char *out, size_t out_size) {
    static char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s/penumbra %s 2>&1", PN_BINARY_DIR, args);
    FILE *p = popen(cmd, "r");
    if (!p) return -1;
    size_t n = fread(out, 1, out_size - 1, p);
    out[n] = '\0';
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

static void test_cli_bad_values(void) {
    char out[4096], args[4096];
    const char *path = pn_test_write_file(tmpdir, "cli.pbrt", pn_test_room_scene(0, 8, 8));
    if (!path) return;
    snprintf(args, sizeof args, "render %s --integrator lightcuts --error 2", path);
    CHECK(run_cli(args, out, sizeof out) == 2);
    CHECK_STR_CONTAINS(out, "--error");
    snprintf(args, sizeof args, "render %s --integrator illumcut --visibility maybe", path);
    CHECK(run_cli(args, out, sizeof out) == 2);
    CHECK_STR_CONTAINS(out, "'exact' or 'sampling'");
    snprintf(args, sizeof args, "render %s --integrator vpl --vpls 0", path);
    CHECK(run_cli(args, out, sizeof out) == 2);
    snprintf(
        args, sizeof args,
        "render %s --integrator illumcut --vpls 500 --visibility sampling -o %s/cli.pfm --stats %s/cli.json --quiet",
        path, tmpdir, tmpdir);
    CHECK(run_cli(args, out, sizeof out) == 0);
    char json_path[512];
    snprintf(json_path, sizeof json_path, "%s/cli.json", tmpdir);
    FILE *f = fopen(json_path, "r");
    CHECK(f != NULL);
    if (f) {
        size_t n = fread(out, 1, sizeof out - 1, f);
        out[n] = '\0';
        fclose(f);
        CHECK_STR_CONTAINS(out, "\"bound_evaluations_per_pixel_mean\"");
        CHECK_STR_CONTAINS(out, "\"vpl_count\": 50");
        CHECK_STR_CONTAINS(out, "\"integrator\": \"illumcut\"");
    }
}

static void setup(void) {
    vpl_test_setup("vpl");
}

static void teardown(void) {
    vpl_test_teardown();
}

PN_TESTS(TEST(setup), TEST(test_contribution_is_eq1), TEST(test_trace_is_deterministic), TEST(test_first_bounce_energy),
         TEST(test_vpl_image_closed_form), TEST(test_no_lights), TEST(test_cli_bad_values), TEST(teardown))
