/* test_dcm.c — the progressive drivers of issue 6 (Guo 1998, Directional Coherence Maps; Painter &
 * Sloan 1989; uniform subsampling): the block-level pieces against closed forms (least-discrepancy
 * direction of straight edges at known angles, the simplicity tests on a straight edge, a corner
 * and two crossing edges, oriented elements on a linear ramp, the object test, the Gaussian
 * filter), then renders through the public API: every driver run to the end equals the `full`
 * render bit for bit (also with a crop and for any thread count), snapshots arrive at the
 * requested percentages and on request, DCM beats uniform subsampling at 6% on a sharp edge,
 * emitters come from the primary rays (exactly, with the integrator's own eye rays), edge blocks
 * are drawn within the segments that visible lines cut them into, smooth blocks filter the noise
 * of their corners, the light guide leaves only a shadow to interpolate in a lamp's glow, bad settings are refused, and the CLI writes its snapshots atomically beside
 * the output. */
#include "harness.h"
#include "render_fields.h"

#include "driver/dcm.h"
#include "film/downsample.h"
#include "penumbra/penumbra.h"

#include <dirent.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

static char tmpdir[256];

/* ---- block-level pieces ---- */

/* Fills loop values of a w x h block from f(x, y). */
static void fill_loop(int w, int h, float (*f)(float, float, const void *), const void *u, float *lum) {
    int n = pn_dcm_loop_length(w, h);
    for (int i = 0; i < n; i++) {
        int x, y;
        pn_dcm_loop_pixel(w, h, i, &x, &y);
        lum[i] = f((float)x, (float)y, u);
    }
}

typedef struct edge {
    float cx, cy, theta, width, lo, hi;
} edge;

/* A straight edge through (cx, cy) along theta: a linear ramp of `width` pixels across it. */
static float edge_value(float x, float y, const void *u) {
    const edge *e = u;
    float d = -(x - e->cx) * sinf(e->theta) + (y - e->cy) * cosf(e->theta);
    float t = d / e->width + 0.5f;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return e->lo + t * (e->hi - e->lo);
}

static void test_loop_geometry(void) {
    int w = 8, h = 4, n = pn_dcm_loop_length(w, h);
    CHECK(n == 24);
    int seen[9][5] = {{0}};
    for (int i = 0; i < n; i++) {
        int x, y;
        pn_dcm_loop_pixel(w, h, i, &x, &y);
        CHECK(x >= 0 && x <= w && y >= 0 && y <= h);
        CHECK(x == 0 || x == w || y == 0 || y == h);
        seen[x][y]++;
        int nx, ny; /* consecutive pixels are 4-neighbours */
        pn_dcm_loop_pixel(w, h, (i + 1) % n, &nx, &ny);
        CHECK(abs(nx - x) + abs(ny - y) == 1);
    }
    for (int x = 0; x <= w; x++)
        for (int y = 0; y <= h; y++) CHECK(seen[x][y] == ((x == 0 || x == w || y == 0 || y == h) ? 1 : 0));
}

static void test_least_discrepancy_exact(void) {
    float lum[64];
    for (int k = 8; k <= 16; k += 8)
        for (int i = 0; i < PN_DCM_DIRECTIONS; i++)
            for (int off = -1; off <= 1; off++) {
                edge e = {0.5f * (float)k + 0.7f * (float)off,
                          0.5f * (float)k - 0.4f * (float)off,
                          (float)(i * M_PI / PN_DCM_DIRECTIONS),
                          1.5f,
                          0.2f,
                          1.0f};
                fill_loop(k, k, edge_value, &e, lum);
                float d[PN_DCM_DIRECTIONS];
                int got = pn_dcm_least_discrepancy(lum, k, k, d);
                CHECK_MSG(got == i, "k %d direction %d offset %d: got %d (d = %g vs %g)", k, i, off, got,
                          (double)d[got], (double)d[i]);
            }
}

static float ramp_value(float x, float y, const void *u) {
    const float *c = u;
    return c[0] + c[1] * x + c[2] * y;
}

static void test_elements_reproduce_linear_ramp(void) {
    const float c[3] = {0.3f, 0.05f, -0.02f};
    float lum[64];
    int sizes[3][2] = {{8, 8}, {4, 4}, {8, 5}};
    for (int s = 0; s < 3; s++) {
        int w = sizes[s][0], h = sizes[s][1];
        fill_loop(w, h, ramp_value, c, lum);
        for (int dir = 0; dir < PN_DCM_DIRECTIONS; dir++)
            for (int y = 0; y <= 2 * h; y++)
                for (int x = 0; x <= 2 * w; x++) {
                    float px = 0.5f * (float)x, py = 0.5f * (float)y, v;
                    pn_dcm_element_value(lum, 1, w, h, dir, px, py, &v);
                    CHECK_NEAR(v, ramp_value(px, py, c), 2e-6);
                }
    }
}

static float sample_fn_inner(void *user, int x, int y) {
    const edge *e = user;
    return edge_value((float)x, (float)y, e);
}

typedef struct shape_fn {
    int kind; /* 0 corner: bright where x > a and y > a; 1 cross: bright in two opposite quadrants */
    float a;
} shape_fn;

static float shape_value(float x, float y, const void *u) {
    const shape_fn *s = u;
    if (s->kind == 0) return (x > s->a && y > s->a) ? 1.0f : 0.1f;
    return ((x > s->a) == (y > s->a)) ? 1.0f : 0.1f;
}

static float shape_inner(void *user, int x, int y) {
    return shape_value((float)x, (float)y, user);
}

static void test_simplicity_tests(void) {
    float lum[64];
    pn_dcm_zero_order z;
    /* A single straight edge at several angles passes the zero- and first-order tests. */
    for (int i = 0; i < 8; i++) {
        edge e = {4.1f, 3.9f, (float)(i * M_PI / 8 + 0.1), 0.8f, 0.1f, 1.0f};
        fill_loop(8, 8, edge_value, &e, lum);
        CHECK(pn_dcm_zero_order_test(lum, 8, 8, &z));
        CHECK(z.transitions == 2);
        CHECK_MSG(pn_dcm_first_order_test(8, 8, &z, sample_fn_inner, &e), "edge at %d", i);
    }
    /* A corner: one span of bright pixels, so two transitions, but the tangents disagree. */
    shape_fn corner = {0, 5.5f};
    fill_loop(8, 8, shape_value, &corner, lum);
    CHECK(pn_dcm_zero_order_test(lum, 8, 8, &z));
    CHECK(z.transitions == 2);
    CHECK(!pn_dcm_first_order_test(8, 8, &z, shape_inner, &corner));
    /* Two crossing edges: four transitions, the zero-order test fails. */
    shape_fn cross = {1, 3.5f};
    fill_loop(8, 8, shape_value, &cross, lum);
    CHECK(!pn_dcm_zero_order_test(lum, 8, 8, &z));
    CHECK(z.transitions == 4);
    /* A flat but noisy boundary (contrast below t_c) has no transitions. */
    for (int i = 0; i < 32; i++) lum[i] = 1.0f + 0.02f * (float)((i * 7) % 5 - 2);
    CHECK(pn_dcm_zero_order_test(lum, 8, 8, &z) && z.transitions == 0);
    /* A single-pixel spike is removed by the filters. */
    for (int i = 0; i < 32; i++) lum[i] = i < 16 ? 1.0f : 0.1f;
    lum[24] = 1.0f;
    CHECK(pn_dcm_zero_order_test(lum, 8, 8, &z) && z.transitions == 2);
}

static void test_object_test_and_contrast(void) {
    int32_t two[8] = {1, 1, 1, 2, 2, 2, 2, 1};
    int32_t three[8] = {1, 1, 3, 2, 2, 2, 2, 1};
    int32_t four_spans[8] = {1, 2, 1, 2, 1, 1, 1, 1};
    int32_t one[8] = {5, 5, 5, 5, 5, 5, 5, 5};
    CHECK(pn_dcm_object_test(two, 8));
    CHECK(pn_dcm_object_test(one, 8));
    CHECK(!pn_dcm_object_test(three, 8));
    CHECK(!pn_dcm_object_test(four_spans, 8));
    float g[4] = {1.0f, 1.5f, 2.0f, 3.0f};
    CHECK_NEAR(pn_dcm_contrast(g), 0.5, 1e-6);
    float z[4] = {0, 0, 0, 0};
    CHECK(pn_dcm_contrast(z) == 0.0f);
}

static void test_gaussian_downsample(void) {
    enum { S = 3, W = 7, H = 5 };
    float src[W * S * H * S * 3], dst[W * H * 3];
    for (int i = 0; i < W * S * H * S * 3; i++) src[i] = 0.25f;
    CHECK(pn_gauss_downsample(src, W * S, H * S, 3, S, dst, W, H, NULL, NULL));
    for (int i = 0; i < W * H * 3; i++) CHECK_NEAR(dst[i], 0.25, 1e-6);
    /* A ramp in x stays a ramp at the output pixel centres away from the borders (symmetric
     * weights). */
    for (int y = 0; y < H * S; y++)
        for (int x = 0; x < W * S; x++)
            for (int c = 0; c < 3; c++) src[(y * W * S + x) * 3 + c] = (float)x;
    CHECK(pn_gauss_downsample(src, W * S, H * S, 3, S, dst, W, H, NULL, NULL));
    for (int x = 2; x < W - 2; x++) CHECK_NEAR(dst[(2 * W + x) * 3], S * x + (S - 1) / 2, 1e-4);
}

/* ---- renders ---- */

/* A floor under a point light with a tilted red quad above it: a sharp shadow and an object
 * boundary. */
static const char *shadow_scene =
    "LookAt 0.3 0.2 4  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 40 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 40 ] \"integer yresolution\" [ 32 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"rgb I\" [ 6 6 6 ] \"point3 from\" [ 0.4 0.3 2.5 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.8 0.2 0.2 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.6 -0.1 0.8  0.1 -0.7 0.8  0.5 0.2 0.8  -0.2 0.6 0.8 ]\n"
    "   \"integer indices\" [ 0 1 2  0 2 3 ]\n";

static pn_scene load_scene(pn_context ctx) {
    const char *path = pn_test_write_file(tmpdir, "shadow.pbrt", shadow_scene);
    pn_scene scene = NULL;
    pn_status st = pn_scene_load(ctx, path, &scene);
    CHECK_MSG(st == PN_OK, "%s", pn_context_error_message(ctx));
    return scene;
}

typedef struct snap_log {
    int count;
    double requested[16], evaluated[16];
    pn_image images[16];
    pn_context ctx;
    int request_on_first;
} snap_log;

static void on_snap(void *user, pn_image image, double requested, double evaluated, double seconds) {
    snap_log *l = user;
    (void)seconds;
    if (l->count < 16) {
        l->requested[l->count] = requested;
        l->evaluated[l->count] = evaluated;
        pn_image_crop(l->ctx, image, 0, 0, pn_image_width(image), pn_image_height(image), &l->images[l->count]);
        l->count++;
    }
    if (l->request_on_first && l->count == 1) pn_render_request_snapshot(l->ctx);
}

static pn_image render_driver(pn_context ctx, pn_scene scene, pn_driver_kind driver, int threads, const float *crop,
                              snap_log *log, const double *percents, int npercents) {
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    s.spp = 2;
    pn_options_set_int(ctx, o, "shadow-rays", 1);
    s.seed = 3;
    s.threads = threads;
    s.driver = driver;
    if (crop) {
        s.has_crop = 1;
        memcpy(s.crop, crop, sizeof s.crop);
    }
    if (log) {
        s.snapshot = on_snap;
        s.snapshot_user = log;
        char list[512] = "";
        for (int i = 0; i < npercents; i++)
            snprintf(list + strlen(list), sizeof list - strlen(list), "%s%.17g", i ? "," : "", percents[i]);
        if (npercents) CHECK(pn_options_set(ctx, o, "snapshots", list) == PN_OK);
    }
    pn_image img = NULL;
    pn_render_stats stats;
    pn_status st = pn_test_render(ctx, scene, &s, &img, &stats);
    pn_options_free(o);
    CHECK_MSG(st == PN_OK, "%s", pn_context_error_message(ctx));
    if (st == PN_OK) CHECK_NEAR(stats.evaluated_percent, 100.0, 1e-9);
    return img;
}

static bool same_pixels(pn_image a, pn_image b) {
    if (!a || !b || pn_image_width(a) != pn_image_width(b) || pn_image_height(a) != pn_image_height(b)) return false;
    size_t n = 3 * (size_t)pn_image_width(a) * (size_t)pn_image_height(a) * sizeof(float);
    return memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(b, 0), n) == 0;
}

static void test_full_refinement_equals_full_render(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_image full = render_driver(ctx, scene, PN_DRIVER_FULL, 2, NULL, NULL, NULL, 0);
    CHECK(full && pn_image_width(full) == 40 && pn_image_height(full) == 32);
    pn_driver_kind drivers[3] = {PN_DRIVER_DCM, PN_DRIVER_UNIFORM, PN_DRIVER_PAINTER};
    for (int i = 0; i < 3; i++)
        for (int threads = 1; threads <= 3; threads += 2) {
            pn_image img = render_driver(ctx, scene, drivers[i], threads, NULL, NULL, NULL, 0);
            CHECK_MSG(same_pixels(full, img), "driver %d, %d threads", (int)drivers[i], threads);
            pn_image_free(img);
        }
    /* A crop: the work window of the crop, the same pixels as the crop of a full render. */
    const float crop[4] = {0.2f, 0.7f, 0.3f, 0.9f};
    pn_image full_crop = render_driver(ctx, scene, PN_DRIVER_FULL, 2, crop, NULL, NULL, 0);
    pn_image dcm_crop = render_driver(ctx, scene, PN_DRIVER_DCM, 2, crop, NULL, NULL, 0);
    CHECK(full_crop && pn_image_width(full_crop) == 20 && pn_image_height(full_crop) == 19);
    CHECK(same_pixels(full_crop, dcm_crop));
    pn_image_free(full_crop);
    pn_image_free(dcm_crop);
    pn_image_free(full);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static double rel_l1(pn_context ctx, pn_image ref, pn_image img) {
    pn_image_metrics m;
    if (pn_image_compare(ctx, ref, img, &m, NULL) != PN_OK) return INFINITY;
    return m.rel_l1;
}

static void test_snapshots_and_error_at_6_percent(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_image full = render_driver(ctx, scene, PN_DRIVER_FULL, 2, NULL, NULL, NULL, 0);
    const double percents[3] = {10.0, 2.0, 6.0}; /* any order */
    double err6[2] = {0, 0};
    pn_driver_kind drivers[2] = {PN_DRIVER_DCM, PN_DRIVER_UNIFORM};
    for (int d = 0; d < 2; d++) {
        snap_log log = {0};
        log.ctx = ctx;
        log.request_on_first = 1;
        pn_image img = render_driver(ctx, scene, drivers[d], 2, NULL, &log, percents, 3);
        /* 2% (then one on request), 6%, 10%; each when that share of the work pixels is reached
         * (the first-order test may add a few pixels past a threshold). */
        CHECK(log.count == 4);
        if (log.count == 4) {
            CHECK(log.requested[0] == 2.0 && log.requested[1] == -1.0 && log.requested[2] == 6.0 &&
                  log.requested[3] == 10.0);
            for (int i = 0; i < 4; i++) {
                if (log.requested[i] > 0)
                    CHECK(log.evaluated[i] >= log.requested[i] && log.evaluated[i] < log.requested[i] + 1.0);
                CHECK(log.images[i] && pn_image_width(log.images[i]) == 40);
            }
            double e2 = rel_l1(ctx, full, log.images[0]), e6 = rel_l1(ctx, full, log.images[2]);
            double e10 = rel_l1(ctx, full, log.images[3]);
            CHECK_MSG(e6 < e2 && e10 < e2, "errors %g %g %g", e2, e6, e10);
            err6[d] = e6;
        }
        for (int i = 0; i < log.count && i < 16; i++) pn_image_free(log.images[i]);
        pn_image_free(img);
    }
    /* The directional coherence map beats bilinear interpolation of a uniform lattice. */
    CHECK_MSG(err6[0] < 0.8 * err6[1], "dcm %g, uniform %g", err6[0], err6[1]);
    pn_image_free(full);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Thin emitting strips, about 3 work pixels wide, on a black background: all the radiance is
 * emitted and seen directly, so the primary rays know it before any pixel is evaluated. The
 * lattice of the regular stage misses the strips; with the emission split the 2% image must hold
 * them anyway, and interpolating raw radiance must not. */
static const char *strips_scene =
    "LookAt 0 0 4  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 40 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 40 ] \"integer yresolution\" [ 32 ]\n"
    "WorldBegin\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n"
    "AttributeBegin\n"
    "AreaLightSource \"diffuse\" \"rgb L\" [ 10 8 6 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.93 -0.7 0  -0.86 -0.7 0  -0.86 0.7 0  -0.93 0.7 0\n"
    "   -0.33 -0.7 0  -0.26 -0.7 0  -0.26 0.7 0  -0.33 0.7 0   0.27 -0.7 0  0.34 -0.7 0  0.34 0.7 0  0.27 0.7 0 ]\n"
    "   \"integer indices\" [ 0 1 2  0 2 3  4 5 6  4 6 7  8 9 10  8 10 11 ]\n"
    "AttributeEnd\n";

/* Renders the strips with `driver` (stop at 2% unless full) and the given eye sampling. */
static pn_image render_strips(pn_context ctx, pn_scene scene, pn_driver_kind driver, uint32_t spp, int raw,
                              pn_render_stats *stats) {
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    s.spp = spp; /* 0: adaptive, with a threshold the strips' pixels reach after a few rays */
    s.threshold = 1e-4;
    pn_options_set_int(ctx, o, "min-eye-rays", 8);
    pn_options_set_int(ctx, o, "shadow-rays", 1);
    s.threads = 2;
    s.driver = driver;
    if (driver != PN_DRIVER_FULL) pn_options_set_double(ctx, o, "stop-at", 2.0);
    pn_options_set_int(ctx, o, "raw-radiance", raw);
    pn_image img = NULL;
    CHECK(pn_test_render(ctx, scene, &s, &img, stats) == PN_OK);
    pn_options_free(o);
    return img;
}

static void test_emitters_from_primary_rays(void) {
    pn_context ctx = pn_context_new();
    const char *path = pn_test_write_file(tmpdir, "strips.pbrt", strips_scene);
    pn_scene scene = NULL;
    CHECK_MSG(pn_scene_load(ctx, path, &scene) == PN_OK, "%s", pn_context_error_message(ctx));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_stats stats;
    /* reference at a fixed 16 eye rays: along the borders the primary buffer traces the
     * integrator's own eye rays, so the emitted light of every pixel is exactly the full
     * render's, evaluated or not. */
    pn_image full = render_strips(ctx, scene, PN_DRIVER_FULL, 16, 0, &stats);
    pn_image img = render_strips(ctx, scene, PN_DRIVER_DCM, 16, 0, &stats);
    /* Only along the strips' borders (the work image has 120 x 96 pixels). */
    CHECK_MSG(stats.primary_grid_pixels > 100 && stats.primary_grid_pixels < 2000, "%llu refined pixels",
              (unsigned long long)stats.primary_grid_pixels);
    double same_rays = rel_l1(ctx, full, img);
    CHECK_MSG(same_rays < 1e-5, "integrator's eye rays: rel L1 %g at 2%%", same_rays);
    pn_image_free(img);
    /* Without demodulation nothing is refined and the lattice misses the strips. */
    img = render_strips(ctx, scene, PN_DRIVER_DCM, 16, 1, &stats);
    CHECK(stats.primary_grid_pixels == 0);
    double raw = rel_l1(ctx, full, img);
    CHECK_MSG(raw > 0.3, "raw radiance: rel L1 %g at 2%%", raw);
    pn_image_free(img);
    pn_image_free(full);
    /* Adaptive eye-ray counts: the 3 x 3 grid over the pixel filter. It and the integrator's eye
     * rays measure a pixel's covered part differently, by a few per cent of the strips' light. */
    full = render_strips(ctx, scene, PN_DRIVER_FULL, 0, 0, &stats);
    img = render_strips(ctx, scene, PN_DRIVER_DCM, 0, 0, &stats);
    CHECK(stats.primary_grid_pixels > 100 && stats.primary_grid_pixels < 2000);
    double grid = rel_l1(ctx, full, img);
    CHECK_MSG(grid > 1e-4 && grid < 0.06, "3 x 3 grid: rel L1 %g at 2%%", grid);
    pn_image_free(img);
    pn_image_free(full);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A flat quad facing the camera and, across a crease, one turned 58 degrees away, both filling
 * the view and lit by a distant light from the camera's side: each face has one constant
 * radiance (1 : 0.53), so an un-evaluated pixel has the value of the evaluated pixels of its own
 * face. The crease is a visible line; the edge blocks along it are drawn from the evaluated
 * pixels of each face, not across the crease. */
static const char *crease_scene =
    "LookAt 0 0 5  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 40 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 40 ] \"integer yresolution\" [ 32 ]\n"
    "WorldBegin\n"
    "LightSource \"distant\" \"point3 from\" [ 0 0 1 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -3 -9 0  0.13 -9 0  0.13 9 0  -3 9 0 ] \"integer indices\" [ 0 1 2  0 2 3 "
    "]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ 0.13 -9 0  5.13 -9 -8  5.13 9 -8  0.13 9 0 ]\n"
    "   \"integer indices\" [ 0 1 2  0 2 3 ]\n";

static void test_segments_across_visible_lines(void) {
    pn_context ctx = pn_context_new();
    const char *path = pn_test_write_file(tmpdir, "crease.pbrt", crease_scene);
    pn_scene scene = NULL;
    CHECK_MSG(pn_scene_load(ctx, path, &scene) == PN_OK, "%s", pn_context_error_message(ctx));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_image img[2] = {NULL, NULL};
    for (int k = 0; k < 2; k++) {
        pn_render_settings s = {0};
        pn_options o = pn_options_new();
        s.options = o;
        s.spp = 16;
        pn_options_set_int(ctx, o, "shadow-rays", 1);
        s.threads = 2;
        s.driver = k == 0 ? PN_DRIVER_FULL : PN_DRIVER_DCM;
        if (k != 0) pn_options_set_double(ctx, o, "stop-at", 3.0);
        pn_render_stats stats;
        CHECK(pn_test_render(ctx, scene, &s, &img[k], &stats) == PN_OK);
        pn_options_free(o);
    }
    /* Measured 0.0139; drawing the edge blocks with elements across the crease gave 0.0193. What
     * is left is the pixels next to the crease, which mix both faces under the pixel filter. */
    double e = rel_l1(ctx, img[0], img[1]);
    CHECK_MSG(e < 0.0165, "crease: rel L1 %g at 3%%", e);
    pn_image_free(img[0]);
    pn_image_free(img[1]);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* A wall lit by a large emitter just in front of it: nearly constant radiance, but noisy pixel
 * estimates (one shadow ray per eye ray over a light that fills the hemisphere). Bilinear
 * interpolation of single noisy corners would spread each corner's noise over its block; the
 * noise-filtered lattice keeps the 3% image about as close to the converged image as the full
 * render at the same eye rays. */
static const char *lit_wall_scene =
    "LookAt 0 0 0.5  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 90 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 40 ] \"integer yresolution\" [ 32 ]\n"
    "WorldBegin\n"
    "AttributeBegin\n"
    "AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -4 -4 0.6  4 -4 0.6  4 4 0.6  -4 4 0.6 ] \"integer indices\" [ 0 2 1  0 3 2 "
    "]\n"
    "AttributeEnd\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -9 -9 0  9 -9 0  9 9 0  -9 9 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n";

/* Renders three variants of the scene `text` (written to tmpdir as `name`), each with the
 * settings set(k, s) gives; false when the scene does not load. */
static bool render_three(pn_context ctx, const char *name, const char *text, void (*set)(int k, pn_render_settings *s),
                         pn_image img[3]) {
    const char *path = pn_test_write_file(tmpdir, name, text);
    pn_scene scene = NULL;
    CHECK_MSG(pn_scene_load(ctx, path, &scene) == PN_OK, "%s", pn_context_error_message(ctx));
    if (!scene) return false;
    for (int k = 0; k < 3; k++) {
        pn_render_settings s = {0};
        s.options = pn_options_new();
        s.threads = 2;
        set(k, &s);
        pn_render_stats stats;
        img[k] = NULL;
        CHECK(pn_test_render(ctx, scene, &s, &img[k], &stats) == PN_OK);
        pn_options_free(s.options);
    }
    pn_scene_free(scene);
    return true;
}

/* k = 0: the converged image; 1: the full render; 2: DCM at 3%. */
static void noisy_wall_settings(int k, pn_render_settings *s) {
    s->spp = k == 0 ? 64 : 4;
    pn_options_set_int(NULL, s->options, "shadow-rays", k == 0 ? 4 : 1);
    s->seed = k == 0 ? 9 : 0;
    s->driver = k == 2 ? PN_DRIVER_DCM : PN_DRIVER_FULL;
    if (k == 2) pn_options_set_double(NULL, s->options, "stop-at", 3.0);
}

static void test_smooth_blocks_filter_noise(void) {
    pn_context ctx = pn_context_new();
    pn_image img[3] = {NULL, NULL, NULL};
    if (render_three(ctx, "wall.pbrt", lit_wall_scene, noisy_wall_settings, img)) {
        /* Measured: full 0.0237, 3% image 0.0259 (0.0288 with the lattice mean alone, --dcm-off
         * smooth-fit); with single corners the 3% image was at 0.0601. */
        double full = rel_l1(ctx, img[0], img[1]), dcm = rel_l1(ctx, img[0], img[2]);
        printf("noisy wall: full render rel L1 %.4f, 3%% image %.4f\n", full, dcm);
        CHECK_MSG(dcm < 1.6 * full, "3%% image %g, full render %g", dcm, full);
    }
    for (int k = 0; k < 3; k++) pn_image_free(img[k]);
    pn_context_free(ctx);
}

/* A point light 0.15 from a wall (a glow falling off as cos^3 / d^2 over a few blocks) and a
 * small square between them that casts a sharp shadow into the glow. The reference integrator
 * with one light has no noise but that of its eye rays, so the full render is near exact. */
static const char *glow_scene =
    "LookAt 0 0 0.5  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 90 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 48 ] \"integer yresolution\" [ 40 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"point3 from\" [ 0.05 0.02 0.15 ] \"rgb I\" [ 1 1 1 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -9 -9 0  9 -9 0  9 9 0  -9 9 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.02 -0.1 0.09  0.03 -0.1 0.09  0.03 -0.05 0.09  -0.02 -0.05 0.09 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n";

/* k = 0: the full render; 1: DCM at 3%; 2: DCM at 3% with the albedo alone. */
static void glow_settings(int k, pn_render_settings *s) {
    s->spp = 16;
    pn_options_set_int(NULL, s->options, "shadow-rays", 1);
    s->driver = k == 0 ? PN_DRIVER_FULL : PN_DRIVER_DCM;
    if (k != 0) pn_options_set_double(NULL, s->options, "stop-at", 3.0);
    pn_options_set_int(NULL, s->options, "no-light-guide", k == 2);
}

/* The light guide (progressive.c): dividing out the unshadowed irradiance leaves the visible
 * fraction to interpolate, so the glow is known from primary rays and only the shadow's border
 * needs evaluated pixels. */
static void test_light_guide_glow(void) {
    pn_context ctx = pn_context_new();
    pn_image img[3] = {NULL, NULL, NULL};
    if (render_three(ctx, "glow.pbrt", glow_scene, glow_settings, img)) {
        /* Measured: 0.0080 guided, 0.0279 with the albedo alone. */
        double guided = rel_l1(ctx, img[0], img[1]), albedo_only = rel_l1(ctx, img[0], img[2]);
        printf("light guide at 3%%: rel L1 %.5f, albedo only %.5f\n", guided, albedo_only);
        CHECK_MSG(guided < 0.01 && guided < 0.5 * albedo_only, "guided %g, albedo only %g", guided, albedo_only);
    }
    for (int k = 0; k < 3; k++) pn_image_free(img[k]);
    pn_context_free(ctx);
}

/* Renders render_three's images for seeds 0 .. seeds - 1 (through *seed, which set() reads) and
 * returns the mean rel L1 of image 1 and of image 2 against image 0; false when the scene failed. */
static bool mean_l1_over_seeds(pn_context ctx, const char *name, const char *text,
                               void (*set)(int k, pn_render_settings *s), uint32_t *seed, uint32_t seeds,
                               const char *what, double *with, double *without) {
    *with = *without = 0.0;
    for (*seed = 0; *seed < seeds; (*seed)++) {
        pn_image img[3] = {NULL, NULL, NULL};
        if (!render_three(ctx, name, text, set, img)) return false;
        double a = rel_l1(ctx, img[0], img[1]), b = rel_l1(ctx, img[0], img[2]);
        printf("%s, seed %u: rel L1 %.5f with, %.5f without\n", what, *seed, a, b);
        *with += a / seeds;
        *without += b / seeds;
        for (int k = 0; k < 3; k++) pn_image_free(img[k]);
    }
    return true;
}

/* k = 0: the converged image; 1: DCM at 3%; 2: DCM at 3% with the lattice mean alone
 * (--dcm-off smooth-fit). */
static void noisy_wall_fit_settings(int k, pn_render_settings *s) {
    noisy_wall_settings(k == 0 ? 0 : 2, s);
    if (k == 2) CHECK(pn_options_set(NULL, s->options, "dcm-off", "smooth-fit") == PN_OK);
}

/* dcm's smooth fit (issue 18): where a smooth block's corner is noisy against its value, it is the
 * plane fitted over the agreeing lattice corners within two steps instead of the mean of its 3 x 3
 * neighbours, which averages more of the corners' noise away on a wall whose shading is smooth.
 * Against the converged image, over two seeds. */
static uint32_t wall_seed;
static void noisy_wall_fit_seeded(int k, pn_render_settings *s) {
    noisy_wall_fit_settings(k, s);
    if (k != 0) s->seed = wall_seed;
}

static void test_smooth_fit(void) {
    pn_context ctx = pn_context_new();
    double with, without;
    if (mean_l1_over_seeds(ctx, "wall.pbrt", lit_wall_scene, noisy_wall_fit_seeded, &wall_seed, 2,
                           "noisy wall at 3%, smooth fit", &with, &without))
        CHECK_MSG(with < 0.95 * without, "smooth fit: rel L1 %g, without %g", with, without);
    pn_context_free(ctx);
}

/* A wall with a fine checkerboard (cells of about 3 work pixels, albedo 0.5 against 0.42: a
 * 16% step, under the 30% at which the primary buffer looks closer at the albedo) in the glow of
 * a point light, with a square casting a shadow into it. */
static const char *checker_scene =
    "LookAt 0 0 0.5  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 90 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 48 ] \"integer yresolution\" [ 40 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"point3 from\" [ 0.05 0.02 0.3 ] \"rgb I\" [ 1 1 1 ]\n"
    "Texture \"c\" \"spectrum\" \"checkerboard\" \"float uscale\" [ 96 ] \"float vscale\" [ 96 ]"
    " \"rgb tex1\" [ 0.5 0.5 0.5 ] \"rgb tex2\" [ 0.42 0.42 0.42 ]\n"
    "Material \"diffuse\" \"texture reflectance\" \"c\"\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ] \"point2 uv\" [ 0 0  1 0  1 1  0 1 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.02 -0.1 0.15  0.03 -0.1 0.15  0.03 -0.05 0.15  -0.02 -0.05 0.15 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n";

/* dcm's albedo rays (issue 18): where neighbouring centre rays see albedos 5% apart, the first 16
 * of the integrator's own eye rays give the albedo factor, so that an interpolated pixel's
 * texture is weighed as in the integrator's estimate. Over three seeds, the 6% image of the
 * checkerboard is closer to the full render with them than with the filtered centre rays
 * (measured: rel L1 0.0072 against 0.0146 on average, so the bound is 0.65 times). */
static uint32_t checker_seed;

/* k = 0: the full render; 1: DCM at 6%; 2: DCM at 6% without the albedo rays. */
static void checker_settings(int k, pn_render_settings *s) {
    s->spp = 16;
    s->seed = checker_seed;
    s->driver = k == 0 ? PN_DRIVER_FULL : PN_DRIVER_DCM;
    pn_options_set_int(NULL, s->options, "shadow-rays", 1);
    if (k > 0) pn_options_set_double(NULL, s->options, "stop-at", 6.0);
    if (k == 2) CHECK(pn_options_set(NULL, s->options, "dcm-off", "albedo-rays") == PN_OK);
}

static void test_albedo_rays(void) {
    pn_context ctx = pn_context_new();
    double with, without;
    if (mean_l1_over_seeds(ctx, "checker.pbrt", checker_scene, checker_settings, &checker_seed, 3,
                           "checkerboard at 6%, albedo rays", &with, &without))
        CHECK_MSG(with < 0.65 * without, "albedo rays: rel L1 %g, without %g", with, without);
    pn_context_free(ctx);
}

/* A wall in the glow of a point light close to it, crossed by thin bars slightly in front of it
 * (other objects: visible lines), so that most edge blocks are cut into segments. */
static const char *bars_scene =
    "LookAt 0 0 0.5  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 90 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 48 ] \"integer yresolution\" [ 40 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"point3 from\" [ 0.1 0.05 0.12 ] \"rgb I\" [ 1 1 1 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -9 -9 0  9 -9 0  9 9 0  -9 9 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.3 0.3 0.3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.30 -1 0.02  -0.28 -1 0.02  -0.28 1 0.02  -0.30 1 0.02 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -0.15 -1 0.02  -0.13 -1 0.02  -0.13 1 0.02  -0.15 1 0.02 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ 0.00 -1 0.02  0.02 -1 0.02  0.02 1 0.02  0.00 1 0.02 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ 0.15 -1 0.02  0.17 -1 0.02  0.17 1 0.02  0.15 1 0.02 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ 0.30 -1 0.02  0.32 -1 0.02  0.32 1 0.02  0.30 1 0.02 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -1 -0.21 0.03  1 -0.21 0.03  1 -0.19 0.03  -1 -0.19 0.03 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -1 0.19 0.03  1 0.19 0.03  1 0.21 0.03  -1 0.21 0.03 ]"
    " \"integer indices\" [ 0 1 2  0 2 3 ]\n";

static uint32_t bars_seed;

/* k = 0: the full render; 1: DCM at 6%; 2: DCM at 6% with the guided fill as a weighted mean.
 * Divided by the albedo alone, what is interpolated keeps the glow's smooth gradient. */
static void bars_settings(int k, pn_render_settings *s) {
    s->spp = 16;
    s->seed = bars_seed;
    s->driver = k == 0 ? PN_DRIVER_FULL : PN_DRIVER_DCM;
    pn_options_set_int(NULL, s->options, "shadow-rays", 1);
    pn_options_set_int(NULL, s->options, "no-light-guide", 1);
    if (k > 0) pn_options_set_double(NULL, s->options, "stop-at", 6.0);
    if (k == 2) CHECK(pn_options_set(NULL, s->options, "dcm-off", "linear") == PN_OK);
}

/* dcm's linear fill (issue 18): a pixel of a partly evaluated edge block takes the value of the
 * plane fitted to its segment's evaluated pixels instead of their weighted mean, which follows a
 * gradient instead of flattening it towards the nearest samples. Measured over two seeds: rel L1
 * at 6% 0.0692 / 0.0693 with, 0.0748 / 0.0752 without (0.92 times). */
static void test_linear_fill(void) {
    pn_context ctx = pn_context_new();
    double with, without;
    if (mean_l1_over_seeds(ctx, "bars.pbrt", bars_scene, bars_settings, &bars_seed, 2, "bars at 6%, linear fill", &with,
                           &without))
        CHECK_MSG(with < 0.96 * without, "linear fill: rel L1 %g, without %g", with, without);
    pn_context_free(ctx);
}

/* k = 0: the full render; 1: DCM at 6%; 2: DCM at 6% with the boundary steps in the paper-free
 * order by corner ranges alone (--dcm-off residuals). The bars at twice the film's resolution. */
static void bars_residual_settings(int k, pn_render_settings *s) {
    bars_settings(k, s);
    s->width = 96;
    s->height = 80;
    if (k == 2) CHECK(pn_options_set(NULL, s->options, "dcm-off", "residuals") == PN_OK);
}

/* dcm's residual order (issue 18): a block's next boundary step goes by what its last step found
 * (the largest error of interpolating along its loop) instead of its corners' range, so that
 * blocks where a bar's segment turned out flat give way. Measured over two seeds: rel L1 at 6%
 * 0.0305 / 0.0301 with, 0.0387 / 0.0387 without (0.78 times). */
static void test_residual_order(void) {
    pn_context ctx = pn_context_new();
    double with, without;
    if (mean_l1_over_seeds(ctx, "bars.pbrt", bars_scene, bars_residual_settings, &bars_seed, 2,
                           "bars 96x80 at 6%, residual order", &with, &without))
        CHECK_MSG(with < 0.88 * without, "residual order: rel L1 %g, without %g", with, without);
    pn_context_free(ctx);
}

static void test_stop_and_aovs(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    s.spp = 2;
    s.driver = PN_DRIVER_DCM;
    pn_options_set_double(ctx, o, "stop-at", 8.0);
    s.aovs = PN_AOV_SAMPLING_PATTERN | PN_AOV_BLOCK_MAP | PN_AOV_BLOCK_DIRECTION;
    pn_image img = NULL;
    pn_render_stats stats;
    CHECK(pn_test_render(ctx, scene, &s, &img, &stats) == PN_OK);
    CHECK(stats.evaluated_percent >= 8.0 && stats.evaluated_percent < 9.0);
    CHECK(stats.work_width == 120 && stats.work_height == 96);
    if (img) {
        CHECK(pn_image_layer_count(img) == 4);
        const float *pattern = pn_image_layer_data(img, 1);
        const float *map = pn_image_layer_data(img, 2);
        double sum = 0.0;
        int edges = 0;
        for (int i = 0; i < 40 * 32; i++) {
            sum += (double)pattern[i];
            edges += map[i] > 0.0f;
            CHECK(map[i] >= 0.0f && map[i] <= 3.0f);
        }
        /* the pattern's mean is the evaluated share of the work image */
        CHECK_NEAR(sum / (40 * 32), stats.evaluated_percent / 100.0, 1e-6);
        CHECK(edges > 0 && edges < 40 * 32);
    }
    pn_image_free(img);
    /* bad settings */
    /* Out-of-range driver options are refused where they are set (the declared ranges). */
    pn_render_settings bad = s;
    img = NULL;
    CHECK(pn_options_set_int(ctx, o, "work-scale", 17) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "work-scale");
    pn_context_clear_error(ctx);
    CHECK(pn_options_set_int(ctx, o, "primary-grid", 9) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "primary-grid");
    pn_context_clear_error(ctx);
    bad = s;
    bad.aovs = PN_AOV_DEPTH;
    CHECK(pn_render(ctx, scene, &bad, &img, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_context_clear_error(ctx);
    bad = s;
    bad.driver = (pn_driver_kind)9;
    CHECK(pn_render(ctx, scene, &bad, &img, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_context_clear_error(ctx);
    CHECK(pn_options_set(ctx, o, "snapshots", "0") == PN_ERROR_INVALID_ARGUMENT);
    CHECK(img == NULL);
    pn_context_clear_error(ctx);
    /* An option of another method is refused by pn_render, naming it. */
    bad = s;
    pn_options other = pn_options_new();
    bad.options = other;
    pn_options_set_int(ctx, other, "vpls", 100);
    CHECK(pn_render(ctx, scene, &bad, &img, NULL) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "vpls");
    CHECK(img == NULL);
    pn_options_free(other);
    pn_options_free(o);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* ---- issue 18: the paper variant, every integrator, the preview ---- */

/* Renders the shadow scene under `driver` with the reference integrator (2 eye rays, 1 shadow
 * ray) and the given option pairs (name, value, ..., NULL); stop 0 runs to the end. */
static pn_image render_with(pn_context ctx, pn_scene scene, pn_driver_kind driver, const char *const *pairs,
                            double stop) {
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    s.spp = 2;
    s.seed = 3;
    s.threads = 2;
    s.driver = driver;
    pn_options_set_int(ctx, o, "shadow-rays", 1);
    for (int i = 0; pairs && pairs[i]; i += 2) CHECK(pn_options_set(ctx, o, pairs[i], pairs[i + 1]) == PN_OK);
    if (stop > 0.0) pn_options_set_double(ctx, o, "stop-at", stop);
    pn_image img = NULL;
    pn_status st = pn_render(ctx, scene, &s, &img, NULL);
    CHECK_MSG(st == PN_OK, "%s", pn_context_error_message(ctx));
    pn_options_free(o);
    return img;
}

/* --dcm-variant paper is the paper's DCM: exactly the default with every departure of dcm.c's
 * header switched off one by one (--dcm-off with all of them), which is not the default's image;
 * it interpolates radiance, so the options of our demodulation change nothing in it; and run to
 * the end it equals the full render. Each departure switched off alone changes the 6% image of
 * some setting (those that never did would be dead switches): checked for the ones this scene
 * exercises at 6%. */
static void test_dcm_paper_variant(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    const char *paper[] = {"dcm-variant", "paper", NULL};
    const char *all_off[] = {"dcm-off",
                             "edge-first,order,discrepancy,noise,lattice-mean,segments,demod,guided,albedo-rays,"
                             "linear,residuals,smooth-fit",
                             NULL};
    const char *paper_unguided[] = {"dcm-variant", "paper", "no-light-guide", "1", NULL};
    pn_image a = render_with(ctx, scene, PN_DRIVER_DCM, paper, 6.0);
    pn_image b = render_with(ctx, scene, PN_DRIVER_DCM, all_off, 6.0);
    pn_image c = render_with(ctx, scene, PN_DRIVER_DCM, NULL, 6.0);
    pn_image d = render_with(ctx, scene, PN_DRIVER_DCM, paper_unguided, 6.0);
    CHECK(same_pixels(a, b));
    CHECK(!same_pixels(a, c));
    CHECK(same_pixels(a, d));
    const char *singles[] = {"order", "noise", "lattice-mean", "demod", "guided", "residuals"};
    for (int i = 0; i < 6; i++) {
        const char *one[] = {"dcm-off", singles[i], NULL};
        pn_image e = render_with(ctx, scene, PN_DRIVER_DCM, one, 6.0);
        CHECK_MSG(e && !same_pixels(e, c), "--dcm-off %s changes nothing", singles[i]);
        pn_image_free(e);
    }
    pn_image full = render_with(ctx, scene, PN_DRIVER_FULL, NULL, 0.0);
    pn_image end = render_with(ctx, scene, PN_DRIVER_DCM, paper, 0.0);
    CHECK(same_pixels(full, end));
    pn_image_free(a);
    pn_image_free(b);
    pn_image_free(c);
    pn_image_free(d);
    pn_image_free(full);
    pn_image_free(end);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Every integrator under dcm, run to the end. Those whose pixels do not depend on their batch
 * (PN_CAP_PER_PIXEL: reference, vpl, lightcuts) give the full render bit for bit; contour's
 * spans, contour-mc's blocks and illumcut's batches pool over the pixels of a batch, which a
 * progressive driver fills differently, so they give another estimate of the same image: within
 * a few percent of the full render in rel L1. Integrators without PN_CAP_PROGRESSIVE (ias) are
 * refused by dcm with the reason of their method table entry, and taken by full. */
static void test_every_integrator_under_dcm(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    for (int k = 0; k < pn_method_count(); k++) {
        const pn_method_info *m = pn_method_get(k);
        if (m->role != PN_METHOD_INTEGRATOR) continue;
        bool refused = !(m->capabilities & PN_CAP_PROGRESSIVE);
        pn_image img[2] = {NULL, NULL};
        for (int d = 0; d < 2; d++) {
            pn_render_settings s = {0};
            pn_options o = pn_options_new();
            s.options = o;
            s.integrator = (pn_integrator_kind)m->kind;
            s.driver = d ? PN_DRIVER_DCM : PN_DRIVER_FULL;
            s.spp = (m->capabilities & PN_CAP_SPP) ? 2 : 0;
            s.threshold = (m->capabilities & PN_CAP_SPP) ? 0.0 : 0.05;
            s.seed = 3;
            s.threads = 2;
            s.width = 20;
            s.height = 16;
            if (strstr(m->stats, "vpl")) pn_options_set_int(ctx, o, "vpls", 200);
            pn_status st = pn_render(ctx, scene, &s, &img[d], NULL);
            if (refused && d == 1) {
                CHECK_MSG(st == PN_ERROR_INVALID_ARGUMENT && img[d] == NULL, "%s", m->name);
                CHECK_STR_CONTAINS(pn_context_error_message(ctx), "does not run under the dcm driver: ");
                CHECK_STR_CONTAINS(pn_context_error_message(ctx), "scattered pixels per block");
                pn_context_clear_error(ctx);
            } else {
                CHECK_MSG(st == PN_OK, "%s: %s", m->name, pn_context_error_message(ctx));
            }
            pn_options_free(o);
        }
        if (refused)
            CHECK_MSG(img[0] != NULL, "%s under full", m->name);
        else if (m->capabilities & PN_CAP_PER_PIXEL)
            CHECK_MSG(same_pixels(img[0], img[1]), "%s", m->name);
        else if (img[0] && img[1]) {
            double e = rel_l1(ctx, img[0], img[1]);
            CHECK_MSG(e < 0.05, "%s: rel L1 %g", m->name, e);
        }
        pn_image_free(img[0]);
        pn_image_free(img[1]);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* The progress note of the progressive drivers (the CLI's progress bar shows it): after every
 * chunk, the evaluated share of the work pixels, never decreasing and 100 at the end, and the
 * error estimate, unknown (-1) until two previews exist and then the rel L1 change between them. */
typedef struct note_log {
    int count, estimates;
    double last_percent;
    bool decreasing, bad_estimate;
} note_log;

static void on_note(void *user, double percent, double estimate) {
    note_log *l = user;
    if (percent < l->last_percent) l->decreasing = true;
    l->last_percent = percent;
    if (estimate >= 0.0) l->estimates++;
    if (!(estimate == -1.0 || (estimate >= 0.0 && estimate < 10.0))) l->bad_estimate = true;
    l->count++;
}

static void test_progress_note(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = load_scene(ctx);
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    char prev[600];
    snprintf(prev, sizeof prev, "%s/note-preview.pfm", tmpdir);
    pn_render_settings s = {0};
    pn_options o = pn_options_new();
    s.options = o;
    s.spp = 2;
    s.threads = 2;
    s.driver = PN_DRIVER_DCM;
    note_log log = {0, 0, 0.0, false, false};
    s.progress_user = &log;
    s.progress_note = on_note;
    CHECK(pn_options_set(ctx, o, "preview", prev) == PN_OK);
    CHECK(pn_options_set(ctx, o, "preview-every", "0.000001") == PN_OK);
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &s, &img, NULL) == PN_OK);
    CHECK_MSG(log.count >= 3 && log.estimates >= 1, "%d notes, %d estimates", log.count, log.estimates);
    CHECK(!log.decreasing && !log.bad_estimate);
    CHECK_NEAR(log.last_percent, 100.0, 1e-9);
    pn_image shown = NULL;
    CHECK(pn_image_read(ctx, prev, &shown) == PN_OK);
    CHECK(same_pixels(img, shown));
    pn_image_free(shown);
    pn_image_free(img);
    pn_options_free(o);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* ---- CLI ---- */

static int run(const char *const *args, const char *err_path) {
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        FILE *e = freopen(err_path, "w", stderr);
        (void)e;
        execv(PN_CLI_PATH, (char *const *)args);
        _exit(127);
    }
    int status = 0;
    if (waitpid(pid, &status, 0) != pid) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

static void test_cli_snapshots(void) {
    char scene[512], out[512], err[512], snap6[512], snap2[512];
    snprintf(scene, sizeof scene, "%s/shadow.pbrt", tmpdir);
    pn_test_write_file(tmpdir, "shadow.pbrt", shadow_scene);
    snprintf(out, sizeof out, "%s/snap/out.exr", tmpdir);
    snprintf(err, sizeof err, "%s/cli.err", tmpdir);
    snprintf(snap6, sizeof snap6, "%s/snap/out-6pct.exr", tmpdir);
    snprintf(snap2, sizeof snap2, "%s/snap/out-2.5pct.exr", tmpdir);
    char dir[512];
    snprintf(dir, sizeof dir, "%s/snap", tmpdir);
    mkdir(dir, 0755);
    const char *args[] = {PN_CLI_PATH, "render", scene,         "-o",    out,       "--driver", "dcm",
                          "--spp",     "2",      "--snapshots", "2.5,6", "--quiet", NULL};
    CHECK(run(args, err) == 0);
    pn_context ctx = pn_context_new();
    pn_image a = NULL, b = NULL, c = NULL;
    CHECK(pn_image_read(ctx, snap6, &a) == PN_OK);
    CHECK(pn_image_read(ctx, snap2, &b) == PN_OK);
    CHECK(pn_image_read(ctx, out, &c) == PN_OK);
    CHECK(a && pn_image_width(a) == 40 && pn_image_height(a) == 32);
    /* atomic writes: nothing but the three images in the folder (no temporary left behind) */
    DIR *d = opendir(dir);
    int files = 0;
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.') continue;
        files++;
        CHECK_MSG(strstr(e->d_name, ".tmp") == NULL, "leftover %s", e->d_name);
    }
    if (d) closedir(d);
    CHECK(files == 3);
    pn_image_free(a);
    pn_image_free(b);
    pn_image_free(c);
    pn_context_free(ctx);
    /* timed snapshots: with a tiny interval one is written after every chunk of pixels, named by
     * the evaluated percentage with one decimal */
    char out2[512];
    snprintf(out2, sizeof out2, "%s/timed.pfm", tmpdir);
    const char *timed[] = {PN_CLI_PATH, "render",           scene,      "-o",      out2, "--driver", "uniform", "--spp",
                           "1",         "--snapshot-every", "0.000001", "--quiet", NULL};
    CHECK(run(timed, err) == 0);
    int timed_files = 0;
    d = opendir(tmpdir);
    while (d && (e = readdir(d)) != NULL)
        if (strncmp(e->d_name, "timed-", 6) == 0 && strstr(e->d_name, "pct.pfm")) timed_files++;
    if (d) closedir(d);
    CHECK_MSG(timed_files >= 3, "%d timed snapshots", timed_files);
    /* bad options */
    const char *bad1[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "fast", NULL};
    CHECK(run(bad1, err) == 2);
    const char *bad2[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--snapshots", "6,abc", NULL};
    CHECK(run(bad2, err) == 2);
    const char *bad3[] = {PN_CLI_PATH, "render", scene, "-o", out, "--snapshots", "6", NULL};
    CHECK(run(bad3, err) == 2);
    const char *bad4[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--primary-grid", "9", NULL};
    CHECK(run(bad4, err) == 2);
    const char *bad5[] = {PN_CLI_PATH, "render", scene, "-o", out, "--primary-grid", "2", NULL};
    CHECK(run(bad5, err) == 2);
    const char *bad6[] = {PN_CLI_PATH, "render", scene, "-o", out, "--no-light-guide", NULL};
    CHECK(run(bad6, err) == 2);
    const char *bad7[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--no-light-guide=1", NULL};
    CHECK(run(bad7, err) == 2);
}

/* --preview: the file is rewritten while the render runs and once at the end, each time
 * atomically (no temporary left behind); the last preview is the output image; bad previews and
 * variants are refused with exit status 2 and a message naming them. */
static void test_cli_preview(void) {
    char scene[512], out[600], prev[600], err[512], dir[512];
    snprintf(scene, sizeof scene, "%s/shadow.pbrt", tmpdir);
    pn_test_write_file(tmpdir, "shadow.pbrt", shadow_scene);
    snprintf(dir, sizeof dir, "%s/preview", tmpdir);
    mkdir(dir, 0755);
    snprintf(out, sizeof out, "%s/out.exr", dir);
    snprintf(prev, sizeof prev, "%s/watch.exr", dir);
    snprintf(err, sizeof err, "%s/preview.err", tmpdir);
    const char *args[] = {PN_CLI_PATH, "render", scene, "-o",        out,  "--driver",
                          "dcm",       "--spp",  "2",   "--preview", prev, "--preview-every",
                          "0.000001",  NULL};
    CHECK(run(args, err) == 0);
    FILE *e = fopen(err, "r");
    int lines = 0;
    char line[1024];
    while (e && fgets(line, sizeof line, e))
        if (strstr(line, "preview") && strstr(line, "estimated error")) lines++;
    if (e) fclose(e);
    CHECK_MSG(lines >= 3, "%d preview lines", lines);
    pn_context ctx = pn_context_new();
    pn_image a = NULL, b = NULL;
    CHECK(pn_image_read(ctx, out, &a) == PN_OK);
    CHECK(pn_image_read(ctx, prev, &b) == PN_OK);
    CHECK(same_pixels(a, b));
    pn_image_free(a);
    pn_image_free(b);
    pn_context_free(ctx);
    DIR *d = opendir(dir);
    int files = 0;
    struct dirent *de;
    while (d && (de = readdir(d)) != NULL) {
        if (de->d_name[0] == '.') continue;
        files++;
        CHECK_MSG(strstr(de->d_name, ".tmp") == NULL, "leftover %s", de->d_name);
    }
    if (d) closedir(d);
    CHECK(files == 2);
    const char *bad1[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--preview", "x.jpg", NULL};
    CHECK(run(bad1, err) == 2);
    e = fopen(err, "r");
    bool named = false;
    while (e && fgets(line, sizeof line, e)) named = named || strstr(line, "x.jpg: the preview must be") != NULL;
    if (e) fclose(e);
    CHECK(named);
    const char *bad2[] = {PN_CLI_PATH, "render",  scene,           "-o",    out,
                          "--driver",  "painter", "--dcm-variant", "paper", NULL};
    CHECK(run(bad2, err) == 2);
    const char *bad3[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--dcm-variant", "guo", NULL};
    CHECK(run(bad3, err) == 2);
    const char *bad4[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--preview-every", "0", NULL};
    CHECK(run(bad4, err) == 2);
    const char *bad5[] = {PN_CLI_PATH, "render", scene, "-o", out, "--preview", prev, NULL};
    CHECK(run(bad5, err) == 2);
    const char *bad6[] = {PN_CLI_PATH, "render", scene, "-o", out, "--driver", "dcm", "--integrator", "ias", NULL};
    CHECK(run(bad6, err) == 2);
}

static void test_setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_dcm_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        fprintf(stderr, "mkdtemp failed\n");
        exit(1);
    }
}

/* Removes the files of the temporary folder (one level of subfolders) and the folder. */
static void remove_tree(const char *path, int depth) {
    DIR *d = opendir(path);
    struct dirent *e;
    while (d && (e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        char child[1024];
        size_t lp = strlen(path), ln = strlen(e->d_name);
        if (lp + ln + 2 > sizeof child) continue;
        memcpy(child, path, lp);
        child[lp] = '/';
        memcpy(child + lp + 1, e->d_name, ln + 1);
        if (unlink(child) != 0 && depth > 0) remove_tree(child, depth - 1);
    }
    if (d) closedir(d);
    rmdir(path);
}

static void test_cleanup(void) {
    remove_tree(tmpdir, 1);
}

PN_TESTS(TEST(test_setup), TEST(test_loop_geometry), TEST(test_least_discrepancy_exact),
         TEST(test_elements_reproduce_linear_ramp), TEST(test_simplicity_tests), TEST(test_object_test_and_contrast),
         TEST(test_gaussian_downsample), TEST(test_full_refinement_equals_full_render),
         TEST(test_snapshots_and_error_at_6_percent), TEST(test_emitters_from_primary_rays),
         TEST(test_segments_across_visible_lines), TEST(test_smooth_blocks_filter_noise), TEST(test_smooth_fit),
         TEST(test_light_guide_glow), TEST(test_albedo_rays), TEST(test_linear_fill), TEST(test_residual_order),
         TEST(test_stop_and_aovs), TEST(test_cli_snapshots), TEST(test_dcm_paper_variant),
         TEST(test_every_integrator_under_dcm), TEST(test_progress_note), TEST(test_cli_preview), TEST(test_cleanup))
