/* test_projection_light.c — pbrt-v4's "projection" light (lights/projection.c): closed-form
 * irradiance inside and outside the frustum with pbrt-v4's scale / power normalisation worked out
 * here by hand, the pixel each direction reads (a two-colour image through a rotated light, and a
 * render through a camera at the light's pose), a chi-square test of the emission sampling that
 * starts VPL light paths together with the unbiasedness of its weights against the exact
 * per-pixel solid angles, the first-bounce VPL energy, agreement of the reference, ias, vpl and
 * lightcuts integrators on one small scene, and bad input (file:line:column, exit 3). */
#include "harness.h"
#include "stats_checks.h"

#include "core/rng.h"
#include "lights/lights.h"
#include "lights/vpl.h"
#include "penumbra/penumbra.h"
#include "scene/scene.h"
#include "shade/bounds.h"

#include <stdint.h>
#include <sys/wait.h>
#include <unistd.h>

#define PI_D 3.14159265358979323846

static char tmpdir[256];

static void quiet_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static bool write_pfm(const char *name, const float *rgb, int w, int h) {
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    FILE *f = fopen(path, "wb");
    if (!f) return false;
    const uint32_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    fprintf(f, "PF\n%d %d\n%s\n", w, h, first == 1 ? "-1" : "1");
    /* PFM rows run from the bottom of the image up; rgb is top row first. */
    for (int y = h - 1; y >= 0; y--) fwrite(rgb + (size_t)y * (size_t)w * 3, sizeof(float), (size_t)w * 3, f);
    return fclose(f) == 0;
}

/* A scene: a camera at the origin looking down +z, a film, `world` after WorldBegin. */
static const char *scene_text(int film_w, int film_h, double cam_fov, const char *world) {
    static char text[8192];
    snprintf(text, sizeof text,
             "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" [ %g ]\n"
             "Film \"rgb\" \"integer xresolution\" [ %d ] \"integer yresolution\" [ %d ]\n"
             "PixelFilter \"box\"\nWorldBegin\n%s\n",
             cam_fov, film_w, film_h, world);
    return text;
}

static pn_scene load(pn_context ctx, const char *name, const char *text) {
    const char *path = pn_test_write_file(tmpdir, name, text);
    pn_scene scene = NULL;
    if (!path || pn_scene_load(ctx, path, &scene) != PN_OK) return NULL;
    return scene;
}

static const pn_light *find_projection(pn_scene scene) {
    const pn_lights *L = scene ? scene->lights : NULL;
    for (int i = 0; L && i < L->count; i++)
        if (L->lights[i].kind == PN_LIGHT_PROJECTION) return &L->lights[i];
    return NULL;
}

static double lum_d(double r, double g, double b) {
    return 0.2126 * r + 0.7152 * g + 0.0722 * b;
}

/* pbrt-v4's screen window: the shorter image side spans [-1, 1]. */
static void window(int w, int h, double *sx, double *sy) {
    double aspect = (double)w / (double)h;
    *sx = aspect > 1.0 ? aspect : 1.0;
    *sy = aspect > 1.0 ? 1.0 : 1.0 / aspect;
}

/* pbrt-v4's "power" divisor, by hand: A = (2 sx t)(2 sy t) times the mean over pixel centres of
 * luminance(rgb) cos^3 (ProjectionLight::Create). */
static double pbrt_unit_power(const float *rgb, int w, int h, double fov) {
    double sx, sy, t = tan(fov * PI_D / 360.0), sum = 0.0;
    window(w, h, &sx, &sy);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double u = (x + 0.5) / w, v = (y + 0.5) / h;
            double px = (2.0 * u - 1.0) * sx * t, py = (2.0 * v - 1.0) * sy * t;
            double c = 1.0 / sqrt(1.0 + px * px + py * py);
            const float *p = rgb + 3 * (y * w + x);
            sum += lum_d(p[0], p[1], p[2]) * c * c * c;
        }
    return 4.0 * t * t * sx * sy * sum / (w * h);
}

/* Solid angle of the rectangular pyramid over [x0, x1] x [y0, y1] of the plane z = 1, from the
 * integral of cos^3 over the plane: F(x, y) = atan(x y / sqrt(1 + x^2 + y^2)). */
static double plane_rect_solid_angle(double x0, double x1, double y0, double y1) {
#define F(a, b) atan((a) * (b) / sqrt(1.0 + (a) * (a) + (b) * (b)))
    return F(x1, y1) - F(x0, y1) - F(x1, y0) + F(x0, y0);
#undef F
}

/* ---- irradiance closed form ------------------------------------------------------------- */

/* A constant image c through a light at the origin looking down +z; receivers on the plane z = h
 * facing it. E = I cos / r^2 = I h / r^3 inside the frustum (|x| <= sx t h, |y| <= sy t h), 0
 * outside, I = scale c; with "power" P, I = scale P c / pbrt_unit_power (pbrt-v4 keeps "scale" as
 * a factor on top). Also the flux through the footprint, integrated from the library's irradiance
 * on a midpoint grid, against luminance(I) times the frustum's exact solid angle. */
static void check_constant(int w, int h, double fov, double scale, double power) {
    const double c[3] = {0.8, 0.5, 0.2}, hz = 2.0;
    float *rgb = malloc(3 * (size_t)w * (size_t)h * sizeof *rgb);
    for (int i = 0; i < w * h; i++)
        for (int k = 0; k < 3; k++) rgb[3 * i + k] = (float)c[k];
    CHECK(write_pfm("const.pfm", rgb, w, h));
    char world[1024];
    snprintf(world, sizeof world,
             "LightSource \"projection\" \"string filename\" \"const.pfm\" \"float fov\" [ %g ] "
             "\"float scale\" [ %g ] %s",
             fov, scale, power > 0.0 ? "\"float power\" [ 10 ]" : "");
    CHECK(power == 0.0 || power == 10.0);
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load(ctx, "const.pbrt", scene_text(8, 8, 40, world));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    const pn_light *l = find_projection(scene);
    CHECK(l != NULL);
    if (l) {
        const pn_lights *L = scene->lights;
        double I = scale;
        if (power > 0.0) I = scale * power / pbrt_unit_power(rgb, w, h, fov);
        CHECK_NEAR(l->emit.x, I, 1e-5 * I);
        double sx, sy, t = tan(fov * PI_D / 360.0);
        window(w, h, &sx, &sy);
        double X = sx * t * hz, Y = sy * t * hz;
        pn_rng rng;
        pn_rng_seed(&rng, 1234, (uint64_t)(w * 100 + h));
        int inside = 0, wrong = 0;
        for (int k = 0; k < 4000; k++) {
            double x = (2.0 * (double)pn_rng_float(&rng) - 1.0) * 1.5 * X,
                   y = (2.0 * (double)pn_rng_float(&rng) - 1.0) * 1.5 * Y;
            double ex = fabs(fabs(x) - X) / X, ey = fabs(fabs(y) - Y) / Y;
            if (ex < 1e-3 || ey < 1e-3) continue; /* within rounding of the frustum's side */
            bool in = fabs(x) < X && fabs(y) < Y;
            double r = sqrt(x * x + y * y + hz * hz);
            vec3 p = v3((float)x, (float)y, (float)hz), n = v3(0, 0, -1);
            pn_light_sample s;
            bool ok = pn_light_sample_point(L, l, p, 0.5f, 0.5f, &s);
            double e = (double)pn_light_irradiance_estimate(L, l, p, n);
            if (in) {
                inside++;
                double want[3];
                for (int q = 0; q < 3; q++) want[q] = I * c[q] * hz / (r * r * r);
                if (!ok || !s.delta) {
                    wrong++;
                    continue;
                }
                double cosr = (double)v3_dot(s.wi, n);
                double got[3] = {(double)s.radiance.x * cosr, (double)s.radiance.y * cosr, (double)s.radiance.z * cosr};
                for (int q = 0; q < 3; q++)
                    if (fabs(got[q] - want[q]) > 1e-4 * want[q]) wrong++;
                double wl = lum_d(want[0], want[1], want[2]);
                if (fabs(e - wl) > 1e-4 * wl) wrong++;
            } else {
                if ((ok && !v3_is_zero(s.radiance)) || e != 0.0) wrong++;
            }
        }
        CHECK(inside > 500);
        CHECK_MSG(wrong == 0, "%dx%d fov %g: %d wrong of 4000 receivers (%d inside)", w, h, fov, wrong, inside);
        /* Flux through the footprint = luminance(I) * solid angle of the frustum. */
        const int G = 400;
        double flux = 0.0;
        for (int j = 0; j < G; j++)
            for (int i = 0; i < G; i++) {
                double x = (2.0 * (i + 0.5) / G - 1.0) * X, y = (2.0 * (j + 0.5) / G - 1.0) * Y;
                flux += (double)pn_light_irradiance_estimate(L, l, v3((float)x, (float)y, (float)hz), v3(0, 0, -1));
            }
        flux *= (2.0 * X / G) * (2.0 * Y / G);
        double omega = plane_rect_solid_angle(-sx * t, sx * t, -sy * t, sy * t);
        double want = I * lum_d(c[0], c[1], c[2]) * omega;
        CHECK_MSG(fabs(flux - want) <= 1e-3 * want, "flux %.6g, luminance(I) * frustum solid angle %.6g", flux, want);
        if (power > 0.0)
            fprintf(stderr, "  %dx%d fov %g: flux / (scale power) = %.5f (pbrt-v4 normalises by a pixel-centre sum)\n",
                    w, h, fov, flux / (scale * power));
        pn_scene_info info;
        CHECK(pn_scene_get_info(scene, &info) == PN_OK && info.lights_projection == 1);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
    free(rgb);
}

static void test_irradiance_closed_form(void) {
    check_constant(8, 4, 40.0, 3.0, 0.0);  /* wide image */
    check_constant(3, 6, 30.0, 0.5, 0.0);  /* tall image: sy = 2 */
    check_constant(8, 4, 40.0, 2.0, 10.0); /* "power" 10 */
    check_constant(5, 5, 120.0, 1.0, 10.0);
}

/* ---- which pixel a direction reads ----------------------------------------------------------- */

/* 5 x 3: red where (x + 2 y) % 3 == 0, else blue; no symmetry in either axis. */
static bool is_red(int x, int y) {
    return (x + 2 * y) % 3 == 0;
}

static void two_colour_image(float *rgb) {
    for (int y = 0; y < 3; y++)
        for (int x = 0; x < 5; x++) {
            float *p = rgb + 3 * (y * 5 + x);
            p[0] = is_red(x, y) ? 2.0f : 0.0f;
            p[1] = 0.0f;
            p[2] = is_red(x, y) ? 0.0f : 1.0f;
        }
}

/* The light placed by "Translate 1 2 3 Rotate 60 1 0 0": a receiver p reads, by pbrt-v4's
 * definitions, the pixel of q = flip_y(R^T (p - o)) projected to the screen. */
static void test_two_colour_pixels(void) {
    float rgb[3 * 15];
    two_colour_image(rgb);
    CHECK(write_pfm("two.pfm", rgb, 5, 3));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load(ctx, "two.pbrt",
                          scene_text(8, 8, 40,
                                     "AttributeBegin\nTranslate 1 2 3\nRotate 60 1 0 0\n"
                                     "LightSource \"projection\" \"string filename\" \"two.pfm\" \"float fov\" [ 50 ]\n"
                                     "AttributeEnd\n"));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    const pn_light *l = find_projection(scene);
    CHECK(l != NULL);
    if (l) {
        const double th = 60.0 * PI_D / 180.0, ct = cos(th), st = sin(th), t = tan(25.0 * PI_D / 180.0);
        double sx = 5.0 / 3.0, sy = 1.0;
        pn_rng rng;
        pn_rng_seed(&rng, 99, 2);
        int counted[2] = {0, 0}, wrong = 0;
        for (int k = 0; k < 6000; k++) {
            /* A point in front of the light: light-space direction in a cone, any distance. */
            double lx = (2.0 * (double)pn_rng_float(&rng) - 1.0) * 2.2 * t,
                   ly = (2.0 * (double)pn_rng_float(&rng) - 1.0) * 1.3 * t;
            double dist = 0.5 + 4.0 * (double)pn_rng_float(&rng);
            /* world = o + R (lx, ly, 1) * dist (R: rotation about x by 60 degrees) */
            double wx = lx, wy = ly * ct - st, wz = ly * st + ct;
            vec3 p = v3((float)(1.0 + dist * wx), (float)(2.0 + dist * wy), (float)(3.0 + dist * wz));
            /* Back to light space by hand, then pbrt's flip and screen. */
            double rx = (double)p.x - 1.0, ry = (double)p.y - 2.0, rz = (double)p.z - 3.0;
            double qx = rx, qy = ry * ct + rz * st, qz = -ry * st + rz * ct;
            qy = -qy;
            double psx = qx / (qz * t), psy = qy / (qz * t);
            double u = (psx + sx) / (2.0 * sx), v = (psy + sy) / (2.0 * sy);
            pn_light_sample s;
            bool ok = pn_light_sample_point(scene->lights, l, p, 0.5f, 0.5f, &s);
            if (fabs(u) < 1e-3 || fabs(u - 1.0) < 1e-3 || fabs(v) < 1e-3 || fabs(v - 1.0) < 1e-3) continue;
            if (u < 0.0 || u > 1.0 || v < 0.0 || v > 1.0) {
                if (ok) wrong++; /* outside the frustum: nothing */
                continue;
            }
            double fx = u * 5.0, fy = v * 3.0;
            if (fabs(fx - round(fx)) < 1e-3 || fabs(fy - round(fy)) < 1e-3) continue; /* pixel edges */
            bool red = is_red((int)fx, (int)fy);
            counted[red]++;
            if (!ok) {
                wrong++;
                continue;
            }
            double d2 = (double)s.dist * (double)s.dist;
            double want_r = red ? 2.0 / d2 : 0.0, want_b = red ? 0.0 : 1.0 / d2;
            if (fabs((double)s.radiance.x - want_r) > 1e-4 / d2 || fabs((double)s.radiance.z - want_b) > 1e-4 / d2 ||
                s.radiance.y != 0.0f)
                wrong++;
        }
        CHECK(counted[0] > 1000 && counted[1] > 500);
        CHECK_MSG(wrong == 0, "%d receivers read the wrong pixel (red %d, blue %d)", wrong, counted[1], counted[0]);
    }
    pn_scene_free(scene);

    /* A camera at the light's pose with the same fov sees the image upright and unmirrored, as
     * pbrt-v4 projects it: film 10 x 6 = 2 x 2 film pixels per image pixel, box filter. */
    scene = load(ctx, "two_render.pbrt",
                 scene_text(10, 6, 50,
                            "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
                            "Shape \"trianglemesh\" \"point3 P\" [ -20 -20 4  20 -20 4  20 20 4  -20 20 4 ] "
                            "\"integer indices\" [ 0 1 2  0 2 3 ]\n"
                            "LightSource \"projection\" \"string filename\" \"two.pfm\" \"float fov\" [ 50 ]\n"));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    if (scene) {
        pn_render_settings rs;
        memset(&rs, 0, sizeof rs);
        rs.integrator = PN_INTEGRATOR_REFERENCE;
        rs.spp = 16;
        rs.threads = 2;
        pn_image img = NULL;
        CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
        if (img) {
            const float *px = pn_image_layer_data(img, 0);
            int wrong = 0;
            for (int y = 0; y < 6; y++)
                for (int x = 0; x < 10; x++) {
                    const float *c = px + 3 * (y * 10 + x);
                    bool red = is_red(x / 2, y / 2);
                    bool looks_red = c[0] > 0.0f && c[2] == 0.0f, looks_blue = c[2] > 0.0f && c[0] == 0.0f;
                    if (red ? !looks_red : !looks_blue) wrong++;
                }
            CHECK_MSG(wrong == 0, "%d of 60 film pixels show the wrong colour", wrong);
        }
        pn_image_free(img);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* ---- emission sampling (VPL light paths) ------------------------------------------------------- */

#define EW 6
#define EH 4
#define SUB 3

static void emission_image(float *rgb) {
    for (int y = 0; y < EH; y++)
        for (int x = 0; x < EW; x++) {
            float *p = rgb + 3 * (y * EW + x);
            float base = (float)((x * 7 + y * 3) % 5); /* includes black pixels */
            p[0] = base;
            p[1] = 0.5f * base + (x == 0 ? 1.0f : 0.0f);
            p[2] = (float)(y + 1) * 0.3f * (base > 0.0f ? 1.0f : 0.0f);
        }
}

/* Directions from pn_projection_sample_direction binned by pixel and SUB x SUB sub-cells of the
 * plane z = 1 against pbrt-v4's table (pixel weight mean(rgb) cos^3 at its centre, uniform on the
 * plane within a pixel); each sample's pdf against pdf_uv / (A cos^3); and E[lum(I) / pdf] against
 * the exact power: sum over pixels of luminance(rgb) times the pixel's exact solid angle. */
static void test_emission_sampling(void) {
    float rgb[3 * EW * EH];
    emission_image(rgb);
    CHECK(write_pfm("emit.pfm", rgb, EW, EH));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load(ctx, "emit.pbrt",
                          scene_text(8, 8, 40,
                                     "AttributeBegin\nTranslate 1 2 3\nRotate 60 1 0 0\n"
                                     "LightSource \"projection\" \"string filename\" \"emit.pfm\" \"float fov\" [ 70 ] "
                                     "\"float scale\" [ 1.5 ]\nAttributeEnd\n"));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    const pn_light *l = find_projection(scene);
    CHECK(l != NULL);
    if (l) {
        const double th = 60.0 * PI_D / 180.0, ct = cos(th), st = sin(th), t = tan(35.0 * PI_D / 180.0);
        double sx, sy;
        window(EW, EH, &sx, &sy);
        double A = 4.0 * t * t * sx * sy;
        /* pbrt-v4's table, by hand. */
        double wsum = 0.0, pw[EW * EH], phi_exact = 0.0;
        for (int y = 0; y < EH; y++)
            for (int x = 0; x < EW; x++) {
                double px = (2.0 * (x + 0.5) / EW - 1.0) * sx * t, py = (2.0 * (y + 0.5) / EH - 1.0) * sy * t;
                double c = 1.0 / sqrt(1.0 + px * px + py * py);
                const float *p = rgb + 3 * (y * EW + x);
                pw[y * EW + x] = ((double)p[0] + (double)p[1] + (double)p[2]) / 3.0 * c * c * c;
                wsum += pw[y * EW + x];
                double x0 = (2.0 * x / EW - 1.0) * sx * t, x1 = (2.0 * (x + 1) / EW - 1.0) * sx * t;
                double y0 = (2.0 * y / EH - 1.0) * sy * t, y1 = (2.0 * (y + 1) / EH - 1.0) * sy * t;
                phi_exact += 1.5 * lum_d(p[0], p[1], p[2]) * plane_rect_solid_angle(x0, x1, y0, y1);
            }
        enum { NB = EW * EH * SUB * SUB };
        static double prob[NB], obs[NB];
        for (int i = 0; i < NB; i++) {
            int pix = i / (SUB * SUB);
            prob[i] = pw[pix] / wsum / (SUB * SUB);
            obs[i] = 0.0;
        }
        const int N = 200000;
        pn_rng rng;
        pn_rng_seed(&rng, 4242, 7);
        int bad_pdf = 0, failed = 0;
        double est = 0.0, est2 = 0.0;
        for (int k = 0; k < N; k++) {
            vec3 w;
            float pdf;
            if (!pn_projection_sample_direction(scene->lights, l, pn_rng_float(&rng), pn_rng_float(&rng), &w, &pdf)) {
                failed++;
                continue;
            }
            /* Light space by hand (inverse rotation, then the flip). */
            double qx = (double)w.x, qy = (double)w.y * ct + (double)w.z * st,
                   qz = -(double)w.y * st + (double)w.z * ct;
            qy = -qy;
            double u = (qx / (qz * t) + sx) / (2.0 * sx), v = (qy / (qz * t) + sy) / (2.0 * sy);
            int bx = (int)(u * EW * SUB), by = (int)(v * EH * SUB);
            if (bx < 0 || by < 0 || bx >= EW * SUB || by >= EH * SUB) {
                failed++;
                continue;
            }
            int pix = (by / SUB) * EW + bx / SUB;
            obs[pix * SUB * SUB + (by % SUB) * SUB + bx % SUB] += 1.0;
            double cz = qz / sqrt(qx * qx + qy * qy + qz * qz);
            double want = pw[pix] / wsum * (EW * EH) / (A * cz * cz * cz);
            if (fabs((double)pdf - want) > 1e-3 * want) bad_pdf++;
            vec3 f = pn_projection_factor(scene->lights, l, w);
            double y = 1.5 * lum_d((double)f.x, (double)f.y, (double)f.z) / (double)pdf;
            est += y;
            est2 += y * y;
        }
        CHECK_MSG(failed == 0, "%d samples failed or left the frustum", failed);
        CHECK_MSG(bad_pdf == 0, "%d sample pdfs differ from pbrt-v4's density", bad_pdf);
        CHECK(pn_test_chi2_ok(obs, prob, NB, (double)(N - failed)));
        double mean = est / N, se = sqrt(fmax(0.0, est2 / N - mean * mean) / N);
        CHECK_MSG(fabs(mean - phi_exact) <= 4.5 * se, "E[lum(I)/pdf] = %.6g, exact power %.6g (se %.2g)", mean,
                  phi_exact, se);
        /* The power VPL paths choose lights by: pbrt-v4's pixel-centre rule, near the exact one. */
        vec3 phi = v3_mul(l->emit, scene->lights->projections[l->env].phi);
        CHECK_NEAR(v3_luminance(phi), phi_exact, 0.02 * phi_exact);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A projection light looking straight down at a square floor (reflectance kd) large enough to
 * catch its whole frustum, nothing else: the first-bounce VPLs re-emit kd times the light's
 * exact power (pi I_v each); the light itself is one omni VPL of intensity scale * peak. */
static void test_vpl_first_bounce(void) {
    float rgb[3 * EW * EH];
    emission_image(rgb);
    CHECK(write_pfm("emit.pfm", rgb, EW, EH));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    const double kd = 0.5;
    pn_scene scene = load(ctx, "floor.pbrt",
                          scene_text(8, 8, 40,
                                     "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
                                     "Shape \"trianglemesh\" \"point3 P\" [ -6 -6 0  6 -6 0  6 6 0  -6 6 0 ] "
                                     "\"integer indices\" [ 0 1 2  0 2 3 ]\n"
                                     "AttributeBegin\nTranslate 0 0 2\nRotate 180 1 0 0\n"
                                     "LightSource \"projection\" \"string filename\" \"emit.pfm\" \"float fov\" [ 70 ] "
                                     "\"float scale\" [ 1.5 ]\nAttributeEnd\n"));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    const pn_light *l = find_projection(scene);
    if (l) {
        double sx, sy, t = tan(35.0 * PI_D / 180.0), phi_exact = 0.0, peak = 0.0;
        window(EW, EH, &sx, &sy);
        for (int y = 0; y < EH; y++)
            for (int x = 0; x < EW; x++) {
                double x0 = (2.0 * x / EW - 1.0) * sx * t, x1 = (2.0 * (x + 1) / EW - 1.0) * sx * t;
                double y0 = (2.0 * y / EH - 1.0) * sy * t, y1 = (2.0 * (y + 1) / EH - 1.0) * sy * t;
                const float *p = rgb + 3 * (y * EW + x);
                phi_exact += 1.5 * (double)p[0] * plane_rect_solid_angle(x0, x1, y0, y1);
                peak = fmax(peak, fmax((double)p[0], fmax((double)p[1], (double)p[2])));
            }
        pn_vpl_settings s = {20001, 1, 0.05f, 5};
        pn_vpl_set set;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &set, &err) == PN_OK);
        double sum = 0.0, sum2 = 0.0;
        int omni = 0;
        for (uint32_t i = 0; i < set.count; i++) {
            const pn_vpl *v = &set.vpls[i];
            if (v->kind == PN_VPL_OMNI) {
                omni++;
                CHECK_NEAR(v->intensity.x, 1.5 * peak, 1e-5 * peak);
                continue;
            }
            double e = PI_D * (double)v->intensity.x; /* red channel */
            sum += e;
            sum2 += e * e;
        }
        CHECK(omni == 1);
        /* Every path hits the floor: sum over paths of the per-path value, se from their spread. */
        /* The VPLs are already divided by the path count n: path i gave n e_i, whose mean is the
         * sum and whose variance is n sum(e^2) - sum^2. */
        double n = (double)set.paths, mean = sum;
        double se = sqrt(fmax(0.0, sum2 * n - sum * sum) / n);
        CHECK_MSG(fabs(mean - kd * phi_exact) <= 5.0 * se + 1e-6,
                  "first-bounce red power %.6g, kd * power %.6g (se %.2g)", mean, kd * phi_exact, se);
        pn_vpl_set_free(&set);
    } else {
        CHECK(l != NULL);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* The cuts' bound for one VPL at one point (shade/bounds.c: M_max G_max I, the degenerate
 * clusters of Lightcuts) is at least the VPL's contribution: checked for the scene's omni VPL at
 * its light, at receivers all around below it with normals towards it. The tests below use it for
 * lights whose image exceeds 1 (the projection light's peak is 4). */
static void check_light_vpl_bound(pn_scene scene, const char *what) {
    pn_vpl_settings s = {1, 1, 0.05f, 5};
    pn_vpl_set set;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_vpl_trace(scene, scene->lights, scene->accel, &s, &set, &err) == PN_OK);
    const pn_vpl *v = NULL;
    for (uint32_t i = 0; i < set.count; i++)
        if (set.vpls[i].kind == PN_VPL_OMNI) v = &set.vpls[i];
    CHECK(v != NULL);
    pn_rng rng;
    pn_rng_seed(&rng, 31, 3);
    int lit = 0, violated = 0;
    double worst = 0.0;
    for (int k = 0; v && k < 5000; k++) {
        pn_vpl_receiver r;
        memset(&r, 0, sizeof r);
        r.p = v3((float)(4.0 * (double)pn_rng_float(&rng) - 2.0), (float)(4.0 * (double)pn_rng_float(&rng) - 2.0),
                 (float)(1.5 * (double)pn_rng_float(&rng)));
        vec3 to = v3_normalize(v3_sub(v->p, r.p));
        r.ng = r.ns = v3_normalize(v3_add(to, v3(0.3f, 0.0f, 0.0f)));
        r.wo = v3(0, 0, 1);
        r.kd = r.kd_w = v3(0.7f, 0.5f, 0.3f);
        vec3 wi;
        float dist;
        vec3 c = pn_vpl_contribution(scene->lights, v, &r, set.min_dist2, &wi, &dist);
        double actual = (double)v3_luminance(c);
        if (actual <= 0.0) continue;
        lit++;
        pn_receiver_bounds rb;
        memset(&rb, 0, sizeof rb);
        rb.lo = rb.hi = r.p;
        rb.n_axis = r.ns;
        rb.r_axis = r.ns;
        rb.kd_max = r.kd;
        pn_receiver_bounds_set_cones(&rb);
        pn_light_bounds lb;
        memset(&lb, 0, sizeof lb);
        lb.kind = PN_VPL_OMNI;
        lb.lo = lb.hi = v->p;
        lb.axis = v3(0, 0, 1);
        pn_light_bounds_set_cone(&lb);
        double bound = (double)pn_bound_error(&rb, &lb, v->intensity, set.min_dist2);
        if (bound < actual * (1.0 - 1e-5)) violated++;
        worst = fmax(worst, actual / bound);
    }
    CHECK(lit > 1000);
    CHECK_MSG(violated == 0, "%s: %d of %d contributions above their bound (worst ratio %.3f)", what, violated, lit,
              worst);
    pn_vpl_set_free(&set);
}

/* A 12 x 12 floor under a light 2 above its centre (`light`: the pbrt lines after the
 * Translate), loaded and bound-checked by check_light_vpl_bound. */
static void check_light_bound_scene(const char *file, const char *light, const char *what) {
    static char world[1024];
    snprintf(world, sizeof world,
             "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
             "Shape \"trianglemesh\" \"point3 P\" [ -6 -6 0  6 -6 0  6 6 0  -6 6 0 ] "
             "\"integer indices\" [ 0 1 2  0 2 3 ]\n"
             "AttributeBegin\nTranslate 0 0 2\n%sAttributeEnd\n",
             light);
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = load(ctx, file, scene_text(8, 8, 40, world));
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    if (scene) check_light_vpl_bound(scene, what);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_vpl_bound_holds(void) {
    float rgb[3 * EW * EH];
    emission_image(rgb);
    CHECK(write_pfm("emit.pfm", rgb, EW, EH));
    check_light_bound_scene("bound.pbrt",
                            "Rotate 180 1 0 0\n"
                            "LightSource \"projection\" \"string filename\" \"emit.pfm\" \"float fov\" [ 70 ]\n",
                            "projection");
}

/* The same for a goniometric light whose image exceeds 1 (up to 4): its VPL carries the image's
 * peak in its intensity and the factor relative to it, as the projection light's. */
static void test_gonio_vpl_bound_holds(void) {
    enum { GW = 16 };
    float rgb[3 * GW * GW];
    for (int i = 0; i < GW * GW; i++)
        for (int c = 0; c < 3; c++) rgb[3 * i + c] = 0.25f + 3.75f * (float)((i * 7 + c) % 23) / 22.0f;
    CHECK(write_pfm("gonio.pfm", rgb, GW, GW));
    check_light_bound_scene("gbound.pbrt", "LightSource \"goniometric\" \"string filename\" \"gonio.pfm\"\n",
                            "goniometric");
}

/* ---- integrators agree ------------------------------------------------------------------------- */

/* A floor lit from above by a projection light (the two-colour image, tilted) and a point light,
 * seen obliquely. The vpl integrator with one bounce is direct light here (a plane does not light
 * itself) and exact per eye ray, as is the reference; both are unbiased estimators of each pixel,
 * with independent pixels, so the mean over pixels of their difference is zero within its
 * standard error (z <= 4). ias, contour (here: the reference's estimator, no polygon lights) and
 * the reference with the light BVH likewise; lightcuts and illumcut are within their relative
 * error bound (1%) of vpl. */
static void test_integrators_agree(void) {
    float rgb[3 * 15];
    two_colour_image(rgb);
    CHECK(write_pfm("two.pfm", rgb, 5, 3));
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    const char *text =
        "LookAt 0 -5 4  0 0 0  0 0 1\nCamera \"perspective\" \"float fov\" [ 45 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 16 ]\nWorldBegin\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "AttributeBegin\nTranslate 0.3 0 3\nRotate 160 1 0 0\n"
        "LightSource \"projection\" \"string filename\" \"two.pfm\" \"float fov\" [ 45 ] \"float scale\" [ 4 ]\n"
        "AttributeEnd\n"
        "LightSource \"point\" \"point3 from\" [ -2 1 2 ] \"rgb I\" [ 1 1 1 ]\n";
    pn_scene scene = load(ctx, "agree.pbrt", text);
    CHECK_MSG(scene != NULL, "%s", pn_context_error_message(ctx));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    enum { NP = 24 * 16 };
    enum { NM = 7 };
    static float imgs[NM][3 * NP];
    const char *names[NM] = {"reference", "reference-bvh", "ias", "vpl", "lightcuts", "illumcut", "contour"};
    bool have[NM] = {false};
    for (int m = 0; m < NM; m++) {
        pn_render_settings rs;
        memset(&rs, 0, sizeof rs);
        rs.threads = 2;
        rs.seed = 11;
        rs.spp = 32;
        rs.options = pn_options_new();
        if (m == 0) rs.integrator = PN_INTEGRATOR_REFERENCE;
        if (m == 1) {
            rs.integrator = PN_INTEGRATOR_REFERENCE;
            CHECK(pn_options_set(ctx, rs.options, "light-sampler", "bvh") == PN_OK);
        }
        if (m == 2) {
            rs.integrator = PN_INTEGRATOR_IAS; /* adaptive, its default threshold: no spp */
            rs.spp = 0;
        }
        if (m == 6) rs.integrator = PN_INTEGRATOR_CONTOUR;
        if (m >= 3 && m <= 5) {
            rs.integrator = m == 3 ? PN_INTEGRATOR_VPL : (m == 4 ? PN_INTEGRATOR_LIGHTCUTS : PN_INTEGRATOR_ILLUMCUT);
            CHECK(pn_options_set_int(ctx, rs.options, "vpls", 200) == PN_OK);
            CHECK(pn_options_set_int(ctx, rs.options, "vpl-depth", 1) == PN_OK);
            CHECK(pn_options_set_double(ctx, rs.options, "vpl-clamp", (double)1e-4f) == PN_OK);
        }
        pn_image img = NULL;
        pn_status st = pn_render(ctx, scene, &rs, &img, NULL);
        pn_options_free(rs.options);
        CHECK_MSG(st == PN_OK, "%s: %s", names[m], pn_context_error_message(ctx));
        if (img) {
            memcpy(imgs[m], pn_image_layer_data(img, 0), sizeof imgs[m]);
            have[m] = true;
        }
        pn_image_free(img);
    }
    /* The projection light must matter: the red pixels of the image reach the floor. */
    if (have[3]) {
        /* The point light is white and the image has no green: R - G and B - G are its share. */
        double red = 0.0, blue = 0.0, green = 0.0;
        for (int i = 0; i < NP; i++) {
            red += (double)imgs[3][3 * i] - (double)imgs[3][3 * i + 1];
            blue += (double)imgs[3][3 * i + 2] - (double)imgs[3][3 * i + 1];
            green += (double)imgs[3][3 * i + 1];
        }
        CHECK_MSG(red > 0.1 * green && blue > 0.1 * green, "red %g blue %g green %g", red, blue, green);
    }
    for (int m = 0; m < NM; m++) {
        if (m == 3 || !have[m] || !have[3]) continue;
        for (int c = 0; c < 3; c++) {
            double sd = 0.0, sd2 = 0.0, base = 0.0;
            for (int i = 0; i < NP; i++) {
                double d = (double)imgs[m][3 * i + c] - (double)imgs[3][3 * i + c];
                sd += d;
                sd2 += d * d;
                base += (double)imgs[3][3 * i + c];
            }
            double mean = sd / NP, se = sqrt(fmax(0.0, sd2 / NP - mean * mean) / NP);
            base /= NP;
            if (m == 4 || m == 5) {
                CHECK_MSG(fabs(mean) <= 0.01 * base + 4.0 * se, "%s channel %d: mean difference %.3g of %.3g (se %.2g)",
                          names[m], c, mean, base, se);
            } else {
                CHECK_MSG(fabs(mean) <= 4.0 * se + 1e-6 * base, "%s channel %d: mean difference %.3g of %.3g (se %.2g)",
                          names[m], c, mean, base, se);
            }
            fprintf(stderr, "  %-14s - vpl, channel %d: %+.3e (se %.1e, mean %.4f)\n", names[m], c, mean, se, base);
        }
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* ---- bad input ---------------------------------------------------------------------------------- */

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

static void expect_bad(const char *name, const char *light_line, const char *where, const char *what) {
    char world[1024], path[1024], args[2048], out[4096];
    snprintf(world, sizeof world, "%s\n", light_line);
    const char *p = pn_test_write_file(tmpdir, name, scene_text(8, 8, 40, world));
    CHECK(p != NULL);
    if (!p) return;
    snprintf(path, sizeof path, "%s", p);
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, quiet_log, NULL);
    pn_scene scene = NULL;
    CHECK(pn_scene_load(ctx, path, &scene) == PN_ERROR_BAD_INPUT);
    CHECK(scene == NULL);
    char loc[1200];
    snprintf(loc, sizeof loc, "%s:%s", path, where);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), loc);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), what);
    pn_scene_free(scene);
    pn_context_free(ctx);
    snprintf(args, sizeof args, "info %s", path);
    CHECK(run_cli(args, out, sizeof out) == 3);
    CHECK_STR_CONTAINS(out, loc);
}

static void test_bad_input(void) {
    float rgb[3 * 4] = {1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, 1};
    CHECK(write_pfm("ok.pfm", rgb, 2, 2));
    /* The scene text puts the LightSource on line 6. */
    expect_bad("nofile.pbrt", "LightSource \"projection\" \"float fov\" [ 30 ]", "6:1:", "\"filename\"");
    expect_bad("fov0.pbrt", "LightSource \"projection\" \"string filename\" \"ok.pfm\" \"float fov\" [ 0 ]",
               "6:", "\"fov\" 0 is outside (0, 180)");
    expect_bad("fov180.pbrt", "LightSource \"projection\" \"string filename\" \"ok.pfm\" \"float fov\" [ 180 ]",
               "6:", "outside (0, 180)");
    expect_bad("missing.pbrt", "LightSource \"projection\" \"string filename\" \"nosuch.pfm\"", "6:", "nosuch.pfm");
    float nan_rgb[3 * 4] = {1, 1, 1, NAN, 1, 1, 1, 1, 1, 1, 1, 1};
    CHECK(write_pfm("nan.pfm", nan_rgb, 2, 2));
    expect_bad("nan.pbrt", "LightSource \"projection\" \"string filename\" \"nan.pfm\"", "6:", "not-a-number");
    /* `info` counts it. */
    char args[2048], out[8192];
    const char *p = pn_test_write_file(
        tmpdir, "info.pbrt", scene_text(8, 8, 40, "LightSource \"projection\" \"string filename\" \"ok.pfm\"\n"));
    snprintf(args, sizeof args, "info %s", p);
    CHECK(run_cli(args, out, sizeof out) == 0);
    CHECK_STR_CONTAINS(out, "projection   1");
    CHECK_STR_CONTAINS(out, "lights         1");
}

static void setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_projection_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void teardown(void) {
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    CHECK(system(cmd) == 0);
}

PN_TESTS(TEST(setup), TEST(test_irradiance_closed_form), TEST(test_two_colour_pixels), TEST(test_emission_sampling),
         TEST(test_vpl_first_bounce), TEST(test_vpl_bound_holds), TEST(test_gonio_vpl_bound_holds),
         TEST(test_integrators_agree), TEST(test_bad_input), TEST(teardown))
