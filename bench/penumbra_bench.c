/* penumbra_bench — the benchmark driver behind `make bench`.
 *
 * Reads a list of fixed cases (scene, reference image, crop window, settings), renders each case
 * several times in a child process of its own (so that peak memory is per case), and writes a
 * Markdown table and a JSON file: median render time with its spread, Mrays/s, shadow and eye
 * rays per pixel, peak memory, the fraction of render time spent inside Embree, and relMSE of the
 * image against the pbrt-v4 reference of the same pixels. Uses only the public header.
 *
 *   penumbra_bench [--config FILE] [--runs N] [--threads N] [--out DIR] [--only NAME|PREFIX*]
 *
 * Config lines: NAME SCENE REFERENCE CROP SETTINGS, where SCENE and REFERENCE may start with
 * "shared/" for ../shared, CROP is x0,x1,y0,y1 in fractions, SETTINGS is a comma list of spp=N,
 * threshold=T, shadow=N, seed=S, max=N, integrator=reference|ias|contour|contour-mc, sampler=irradiance|bvh (reference),
 * group=NAME, csa=SR (ias's cluster solid angle), and for contour grid=N, steps=N, mcthreshold=T.
 * '#' starts a comment.
 *
 * Cases that share a group are one scene rendered by several integrators at several settings. For
 * every non-reference case of a group the bench adds an equal-quality row (the reference's time
 * and shadow rays at the same relMSE, interpolated log-log between the two reference cases whose
 * relMSE brackets it) and an equal-time row (the reference's relMSE at the same time).
 *
 * Progressive drivers (issue 6): driver=dcm|painter|uniform|full and res=WxH in SETTINGS. For the
 * progressive ones the case also renders the `full` driver (the same work image, every pixel
 * evaluated, the same Gaussian) and records, from snapshots of the first run, the relative L1 and
 * L2 error ||E||/||F|| against it and the time at 2, 4, 6, 8, 10, 15, 25 and 50% of the work
 * pixels evaluated: OUT/progressive.md, and the 6% image beside the full one as OUT/NAME-6pct.png
 * and OUT/NAME-full.png. stop=P ends the progressive run at P% of the work pixels (the curve
 * ends there; the time is the snapshots', so it does not change).
 */
#include "penumbra/penumbra.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#define MAX_RUNS 15

typedef struct bench_case {
    char name[128], scene[1024], reference[1024], crop_text[64], settings_text[256];
    char group[64]; /* "" when the case is not part of an equal-quality comparison */
    float crop[4];
    pn_render_settings settings;
    /* method options by name (the library's table) */
    char option_names[16][48], option_values[16][64];
    int option_count;
    int bvh; /* light-sampler=bvh */
} bench_case;

/* The statistics the bench reports, read by name from the render's pn_stats (plain values: a
 * result travels from the forked child through a pipe). */
typedef struct bench_stats {
    int width, height;
    double render_seconds, embree_seconds_estimate, cut_seconds_estimate, pdf_seconds_estimate;
    double mrays_per_second, shadow_rays_per_pixel_mean, eye_rays_per_pixel_mean;
    uint64_t peak_memory_bytes;
} bench_stats;

/* Statistic `name` of the render (0 when its methods do not produce it). */
static double stat_value(pn_stats stats, const char *name) {
    double v = 0.0;
    return pn_stats_get(stats, name, &v) ? v : 0.0;
}

static void read_stats(pn_stats stats, bench_stats *out) {
    out->width = (int)stat_value(stats, "width");
    out->height = (int)stat_value(stats, "height");
    out->render_seconds = stat_value(stats, "render_seconds");
    out->embree_seconds_estimate = stat_value(stats, "embree_seconds_estimate");
    out->cut_seconds_estimate = stat_value(stats, "cut_seconds_estimate");
    out->pdf_seconds_estimate = stat_value(stats, "pdf_seconds_estimate");
    out->mrays_per_second = stat_value(stats, "mrays_per_second");
    out->shadow_rays_per_pixel_mean = stat_value(stats, "shadow_rays_per_pixel_mean");
    out->eye_rays_per_pixel_mean = stat_value(stats, "eye_rays_per_pixel_mean");
    out->peak_memory_bytes = (uint64_t)stat_value(stats, "peak_memory_bytes");
}

typedef struct bench_result {
    int ok;
    char error[512];
    double parse_seconds, bvh_seconds;
    double times[MAX_RUNS];
    int runs;
    double median, min, max;
    bench_stats stats;
    pn_image_metrics metrics;
    int has_metrics;
    int bit_identical; /* all runs gave the same image */
    uint64_t triangles;
    uint32_t lights;
    /* progressive drivers: error and time against the full render per snapshot percentage */
    int curve_n;
    double curve_pct[8], curve_evaluated[8], curve_l1[8], curve_l2[8], curve_seconds[8];
    double full_seconds;
} bench_result;

static const char curve_list[] = "2,4,6,8,10,15,25,50"; /* snapshot percentages */

static const char *shared_dir = "../shared";

static void resolve(const char *in, char *out, size_t n) {
    if (strncmp(in, "shared/", 7) == 0)
        snprintf(out, n, "%s/%s", shared_dir, in + 7);
    else
        snprintf(out, n, "%s", in);
}

/* The case's short names for options of the method table (any table name works as well). */
static const char *const option_aliases[][2] = {
    {"shadow", "shadow-rays"},  {"max", "max-samples"},          {"sampler", "light-sampler"},
    {"stop", "stop-at"},        {"csa", "cluster-solid-angle"},  {"grid", "contour-grid"},
    {"steps", "contour-steps"}, {"mcthreshold", "mc-threshold"},
};

/* Sets the case's method options on o; with_stop 0 leaves stop-at out (the full run). */
static int case_options(const bench_case *bc, pn_options o, int with_stop) {
    for (int i = 0; i < bc->option_count; i++) {
        if (!with_stop && strcmp(bc->option_names[i], "stop-at") == 0) continue;
        if (pn_options_set(NULL, o, bc->option_names[i], bc->option_values[i]) != PN_OK) return 0;
    }
    return 1;
}

static int parse_settings(const char *text, bench_case *bc) {
    pn_render_settings *s = &bc->settings;
    char buf[256];
    snprintf(buf, sizeof buf, "%s", text);
    for (char *tok = strtok(buf, ","); tok; tok = strtok(NULL, ",")) {
        char *eq = strchr(tok, '=');
        if (!eq) return 0;
        *eq = '\0';
        const char *v = eq + 1;
        if (strcmp(tok, "spp") == 0)
            s->spp = (uint32_t)strtoul(v, NULL, 10);
        else if (strcmp(tok, "threshold") == 0)
            s->threshold = strtod(v, NULL);
        else if (strcmp(tok, "seed") == 0)
            s->seed = strtoull(v, NULL, 10);
        else if (strcmp(tok, "group") == 0)
            snprintf(bc->group, sizeof bc->group, "%s", v);
        else if (strcmp(tok, "res") == 0) {
            if (sscanf(v, "%dx%d", &s->width, &s->height) != 2) return 0;
        } else if (strcmp(tok, "integrator") == 0 || strcmp(tok, "driver") == 0) {
            /* Methods by their name in the library's table. */
            pn_method_role role = tok[0] == 'i' ? PN_METHOD_INTEGRATOR : PN_METHOD_DRIVER;
            int m = pn_method_find(role, v);
            if (m < 0) return 0;
            if (role == PN_METHOD_INTEGRATOR)
                s->integrator = (pn_integrator_kind)pn_method_get(m)->kind;
            else
                s->driver = (pn_driver_kind)pn_method_get(m)->kind;
        } else {
            const char *name = tok;
            for (size_t i = 0; i < sizeof option_aliases / sizeof option_aliases[0]; i++)
                if (strcmp(tok, option_aliases[i][0]) == 0) name = option_aliases[i][1];
            if (pn_option_find(name) < 0 || bc->option_count == 16) return 0;
            snprintf(bc->option_names[bc->option_count], sizeof bc->option_names[0], "%s", name);
            snprintf(bc->option_values[bc->option_count], sizeof bc->option_values[0], "%s", v);
            bc->option_count++;
            if (strcmp(name, "light-sampler") == 0) bc->bvh = strcmp(v, "bvh") == 0;
        }
    }
    /* The values must parse against the table. */
    pn_options o = pn_options_new();
    int ok = o && case_options(bc, o, 1);
    pn_options_free(o);
    return ok;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Snapshot callback of progressive cases: error against the full image, time without the time
 * spent here. */
typedef struct curve_state {
    pn_context ctx;
    pn_image full;
    bench_result *r;
    double t0, spent;
    const char *png_6pct;
} curve_state;

static void on_curve_snapshot(void *user, pn_image image, double requested, double evaluated, double seconds) {
    curve_state *cs = user;
    (void)seconds;
    double t = now();
    bench_result *r = cs->r;
    pn_image_metrics m;
    if (requested > 0 && r->curve_n < 8 && pn_image_compare(cs->ctx, cs->full, image, &m, NULL) == PN_OK) {
        r->curve_pct[r->curve_n] = requested;
        r->curve_evaluated[r->curve_n] = evaluated;
        r->curve_l1[r->curve_n] = m.rel_l1;
        r->curve_l2[r->curve_n] = m.rel_l2;
        r->curve_seconds[r->curve_n] = t - cs->t0 - cs->spent;
        r->curve_n++;
        if (requested == 6.0 && cs->png_6pct) pn_image_write(cs->ctx, image, cs->png_6pct, 0.0f);
    }
    cs->spent += now() - t;
}

static const char *bench_out_dir = "bench/results";

static int same_pixels(pn_image a, pn_image b) {
    size_t n = (size_t)pn_image_width(a) * (size_t)pn_image_height(a) * 3u;
    return pn_image_width(a) == pn_image_width(b) && pn_image_height(a) == pn_image_height(b) &&
           memcmp(pn_image_layer_data(a, 0), pn_image_layer_data(b, 0), n * sizeof(float)) == 0;
}

/* Runs one case; called in a child process. */
static void run_case(const bench_case *bc, int runs, int threads, bench_result *r) {
    memset(r, 0, sizeof *r);
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, NULL, NULL);
    pn_scene scene = NULL;
    if (pn_scene_load(ctx, bc->scene, &scene) != PN_OK) {
        snprintf(r->error, sizeof r->error, "%s", pn_context_error_message(ctx));
        pn_context_free(ctx);
        return;
    }
    pn_scene_info info;
    pn_scene_get_info(scene, &info);
    r->parse_seconds = info.parse_seconds;
    r->bvh_seconds = info.bvh_seconds;
    r->triangles = info.triangles;
    r->lights = info.lights_point + info.lights_spot + info.lights_distant + info.lights_infinite +
                info.lights_goniometric + info.lights_area_triangle + info.lights_area_rectangle +
                info.lights_area_disk + info.lights_area_sphere;
    pn_render_settings s = bc->settings;
    pn_options opts = pn_options_new(), full_opts = pn_options_new();
    if (!opts || !full_opts || !case_options(bc, opts, 1) || !case_options(bc, full_opts, 0)) {
        snprintf(r->error, sizeof r->error, "bad options");
        pn_options_free(opts);
        pn_options_free(full_opts);
        return;
    }
    s.options = opts;
    s.threads = threads;
    s.has_crop = 1;
    memcpy(s.crop, bc->crop, sizeof s.crop);
    pn_image first = NULL;
    r->bit_identical = 1;
    curve_state cs = {ctx, NULL, r, 0.0, 0.0, NULL};
    char png_full[1400], png_6pct[1400];
    if (s.driver != PN_DRIVER_DEFAULT && s.driver != PN_DRIVER_FULL) { /* progressive drivers */
        pn_render_settings fs = s;
        fs.driver = PN_DRIVER_FULL;
        fs.options = full_opts; /* stop=P is for the progressive run only */
        double t0 = now();
        if (pn_render(ctx, scene, &fs, &cs.full, NULL) != PN_OK) {
            snprintf(r->error, sizeof r->error, "full render: %s", pn_context_error_message(ctx));
            pn_image_free(cs.full);
            pn_scene_free(scene);
            pn_context_free(ctx);
            return;
        }
        r->full_seconds = now() - t0;
        snprintf(png_full, sizeof png_full, "%s/%s-full.png", bench_out_dir, bc->name);
        snprintf(png_6pct, sizeof png_6pct, "%s/%s-6pct.png", bench_out_dir, bc->name);
        pn_image_write(ctx, cs.full, png_full, 0.0f);
        cs.png_6pct = png_6pct;
        s.snapshot = on_curve_snapshot;
        s.snapshot_user = &cs;
        pn_options_set(NULL, opts, "snapshots", curve_list);
    }
    for (int i = 0; i < runs; i++) {
        pn_image img = NULL;
        double t0 = now();
        cs.t0 = t0;
        cs.spent = 0.0;
        if (i > 0) s.snapshot = NULL; /* the curve comes from the first run */
        pn_stats stats = pn_stats_new();
        pn_status st = stats ? pn_render(ctx, scene, &s, &img, stats) : PN_ERROR_OUT_OF_MEMORY;
        r->times[i] = now() - t0;
        read_stats(stats, &r->stats);
        pn_stats_free(stats);
        if (st != PN_OK) {
            snprintf(r->error, sizeof r->error, "%s", pn_context_error_message(ctx));
            pn_image_free(img);
            pn_image_free(first);
            pn_scene_free(scene);
            pn_context_free(ctx);
            return;
        }
        if (!first)
            first = img;
        else {
            if (!same_pixels(first, img)) r->bit_identical = 0;
            pn_image_free(img);
        }
    }
    r->runs = runs;
    double sorted[MAX_RUNS];
    memcpy(sorted, r->times, (size_t)runs * sizeof(double));
    qsort(sorted, (size_t)runs, sizeof(double), cmp_double);
    r->median = sorted[runs / 2];
    r->min = sorted[0];
    r->max = sorted[runs - 1];
    pn_image ref = NULL, ref_crop = NULL;
    if (bc->reference[0] && pn_image_read(ctx, bc->reference, &ref) == PN_OK) {
        int W = pn_image_width(ref), H = pn_image_height(ref);
        int x0 = (int)ceilf((float)W * bc->crop[0]), x1 = (int)ceilf((float)W * bc->crop[1]);
        int y0 = (int)ceilf((float)H * bc->crop[2]), y1 = (int)ceilf((float)H * bc->crop[3]);
        /* A reference of the crop window's own size (a render of the window alone, e.g. a
         * converged penumbra render) is compared as it is. */
        if (W == pn_image_width(first) && H == pn_image_height(first)) x0 = y0 = 0, x1 = W, y1 = H;
        if (pn_image_crop(ctx, ref, x0, y0, x1 - x0, y1 - y0, &ref_crop) == PN_OK &&
            pn_image_compare(ctx, ref_crop, first, &r->metrics, NULL) == PN_OK)
            r->has_metrics = 1;
        else
            snprintf(r->error, sizeof r->error, "reference: %s", pn_context_error_message(ctx));
    }
    pn_image_free(ref_crop);
    pn_image_free(ref);
    pn_image_free(first);
    pn_image_free(cs.full);
    pn_scene_free(scene);
    pn_context_free(ctx);
    pn_options_free(opts);
    pn_options_free(full_opts);
    r->ok = 1;
}

static int read_config(const char *path, bench_case **out, int *count) {
    FILE *f = fopen(path, "r");
    if (!f) {
        fprintf(stderr, "penumbra_bench: %s: %s\n", path, strerror(errno));
        return 0;
    }
    char line[4096];
    int n = 0, cap = 0, lineno = 0;
    bench_case *cases = NULL;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *hash = strchr(line, '#');
        if (hash) *hash = '\0';
        bench_case bc;
        memset(&bc, 0, sizeof bc);
        char scene[1024], ref[1024];
        int k = sscanf(line, "%127s %1023s %1023s %63s %255s", bc.name, scene, ref, bc.crop_text, bc.settings_text);
        if (k <= 0) continue;
        if (k != 5 || sscanf(bc.crop_text, "%f,%f,%f,%f", &bc.crop[0], &bc.crop[1], &bc.crop[2], &bc.crop[3]) != 4 ||
            !parse_settings(bc.settings_text, &bc)) {
            fprintf(stderr, "penumbra_bench: %s:%d: expected NAME SCENE REFERENCE x0,x1,y0,y1 SETTINGS\n", path,
                    lineno);
            fclose(f);
            free(cases);
            return 0;
        }
        resolve(scene, bc.scene, sizeof bc.scene);
        resolve(ref, bc.reference, sizeof bc.reference);
        if (n == cap) {
            cap = cap ? 2 * cap : 16;
            bench_case *grown = realloc(cases, (size_t)cap * sizeof *cases);
            if (!grown) {
                fclose(f);
                free(cases);
                return 0;
            }
            cases = grown;
        }
        cases[n++] = bc;
    }
    fclose(f);
    *out = cases;
    *count = n;
    return 1;
}

/* --only NAME selects one case; NAME ending in '*' selects every case whose name starts with
 * the rest. */
static int name_matches(const char *pattern, const char *name) {
    size_t n = strlen(pattern);
    if (n > 0 && pattern[n - 1] == '*') return strncmp(pattern, name, n - 1) == 0;
    return strcmp(pattern, name) == 0;
}

/* ---- equal quality and equal time within a group ----------------------------------------- */

typedef struct quality_point {
    double relmse, seconds, rays;
} quality_point;

static int cmp_relmse_desc(const void *a, const void *b) {
    double x = ((const quality_point *)a)->relmse, y = ((const quality_point *)b)->relmse;
    return (x < y) - (x > y);
}

static int cmp_seconds(const void *a, const void *b) {
    double x = ((const quality_point *)a)->seconds, y = ((const quality_point *)b)->seconds;
    return (x > y) - (x < y);
}

/* y at x, on the straight line through (xa, ya) and (xb, yb) in log-log coordinates. */
static double loglog(double x, double xa, double ya, double xb, double yb) {
    if (!(xa > 0.0 && xb > 0.0 && ya > 0.0 && yb > 0.0) || xa == xb) return 0.5 * (ya + yb);
    double t = (log(x) - log(xa)) / (log(xb) - log(xa));
    return exp(log(ya) + t * (log(yb) - log(ya)));
}

static int is_reference(const pn_render_settings *s) {
    return pn_method_find_kind(PN_METHOD_INTEGRATOR, (int)s->integrator) ==
           pn_method_find_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_DEFAULT);
}

/* The reference's cost at relMSE e from its points sorted by decreasing relMSE. Returns 0 when e
 * lies between two points (interpolated), +1 when every point is worse than e (the reference
 * would need more than the most accurate point: the values are lower bounds), -1 when every point
 * is better (upper bounds from the cheapest point). */
static int reference_at_relmse(const quality_point *p, int n, double e, double *seconds, double *rays) {
    if (e < p[n - 1].relmse) {
        *seconds = p[n - 1].seconds;
        *rays = p[n - 1].rays;
        return 1;
    }
    if (e > p[0].relmse) {
        *seconds = p[0].seconds;
        *rays = p[0].rays;
        return -1;
    }
    for (int i = 0; i + 1 < n; i++)
        if (p[i].relmse >= e && e >= p[i + 1].relmse) {
            *seconds = loglog(e, p[i].relmse, p[i].seconds, p[i + 1].relmse, p[i + 1].seconds);
            *rays = loglog(e, p[i].relmse, p[i].rays, p[i + 1].relmse, p[i + 1].rays);
            return 0;
        }
    *seconds = p[n - 1].seconds;
    *rays = p[n - 1].rays;
    return 0;
}

/* The reference's relMSE at time t from its points sorted by increasing time. Returns 0 when
 * interpolated, -1 when t is shorter than the fastest point (the reference had no image that
 * fast: its error at t would be higher, the value is a lower bound), +1 when t is longer than the
 * slowest point (an upper bound). */
static int reference_at_seconds(const quality_point *p, int n, double t, double *relmse) {
    if (t < p[0].seconds) {
        *relmse = p[0].relmse;
        return -1;
    }
    if (t > p[n - 1].seconds) {
        *relmse = p[n - 1].relmse;
        return 1;
    }
    for (int i = 0; i + 1 < n; i++)
        if (p[i].seconds <= t && t <= p[i + 1].seconds) {
            *relmse = loglog(t, p[i].seconds, p[i].relmse, p[i + 1].seconds, p[i + 1].relmse);
            return 0;
        }
    *relmse = p[n - 1].relmse;
    return 0;
}

static void equal_quality(FILE *md, FILE *js, const bench_case *cases, const int *which, const bench_result *res,
                          int n) {
    quality_point *pts = malloc((size_t)(n > 0 ? n : 1) * sizeof *pts);
    if (!pts) return;
    fprintf(md, "\n### Equal quality and equal time against `reference` (per group and light sampler)\n\n"
                "| group | case | baseline | relMSE | time (s) | shadow rays/px | reference time at equal relMSE (s) | "
                "reference shadow rays/px | speed-up | shadow-ray ratio | reference relMSE at equal time | "
                "relMSE ratio at equal time |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    fprintf(js, ",\n  \"equal_quality\": [");
    int first = 1;
    for (int i = 0; i < n; i++) {
        const bench_case *ci = &cases[which[i]];
        const bench_result *ri = &res[i];
        if (!ci->group[0] || is_reference(&ci->settings) || !ri->has_metrics) continue;
        for (int kind = 0; kind < 2; kind++) {
            const int bvh = kind;
            const char *baseline = kind ? "reference, light BVH" : "reference";
            int m = 0;
            for (int j = 0; j < n; j++) {
                const bench_case *cj = &cases[which[j]];
                if (j == i || strcmp(cj->group, ci->group) != 0 || !is_reference(&cj->settings) ||
                    !res[j].has_metrics || cj->bvh != bvh)
                    continue;
                pts[m].relmse = res[j].metrics.relmse;
                pts[m].seconds = res[j].median;
                pts[m].rays = res[j].stats.shadow_rays_per_pixel_mean;
                m++;
            }
            if (m == 0) continue;
            double e = ri->metrics.relmse, t = ri->median, rays = ri->stats.shadow_rays_per_pixel_mean;
            double ref_t, ref_rays, ref_e;
            qsort(pts, (size_t)m, sizeof *pts, cmp_relmse_desc);
            int q = reference_at_relmse(pts, m, e, &ref_t, &ref_rays);
            qsort(pts, (size_t)m, sizeof *pts, cmp_seconds);
            int qt = reference_at_seconds(pts, m, t, &ref_e);
            const char *qmark = q > 0 ? "> " : q < 0 ? "< " : "";
            const char *tmark = qt < 0 ? "> " : qt > 0 ? "< " : "";
            fprintf(md,
                    "| %s | %s | %s | %.3g | %.3f | %.1f | %s%.3f | %s%.1f | %s%.2f× | %s%.2f× | %s%.3g | %s%.2f× |\n",
                    ci->group, ci->name, baseline, e, t, rays, qmark, ref_t, qmark, ref_rays, qmark,
                    t > 0 ? ref_t / t : 0.0, qmark, rays > 0 ? ref_rays / rays : 0.0, tmark, ref_e, tmark,
                    e > 0 ? ref_e / e : 0.0);
            fprintf(js,
                    "%s\n    {\"group\": \"%s\", \"case\": \"%s\", \"baseline\": \"%s\", \"relmse\": %.6g, "
                    "\"seconds\": %.4f, "
                    "\"shadow_rays_per_pixel\": %.3f, \"reference_seconds_equal_relmse\": %.4f, "
                    "\"reference_shadow_rays_equal_relmse\": %.3f, \"equal_relmse_bound\": \"%s\", "
                    "\"reference_relmse_equal_time\": %.6g, \"equal_time_bound\": \"%s\"}",
                    first ? "" : ",", ci->group, ci->name, baseline, e, t, rays, ref_t, ref_rays,
                    q > 0   ? "lower"
                    : q < 0 ? "upper"
                            : "interpolated",
                    ref_e,
                    qt < 0   ? "lower"
                    : qt > 0 ? "upper"
                             : "interpolated");
            first = 0;
        }
    }
    fprintf(js, "\n  ]");
    fprintf(md, "\nA `>` or `<` marks a bound: no reference case of the group reached that relMSE (or ran "
                "that fast), so the nearest one is shown.\n");
    free(pts);
}

int main(int argc, char **argv) {
    const char *config = "bench/bench.conf", *out_dir = "bench/results", *only = NULL;
    int runs = 3, threads = 0;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--config") == 0 && i + 1 < argc)
            config = argv[++i];
        else if (strcmp(argv[i], "--runs") == 0 && i + 1 < argc)
            runs = atoi(argv[++i]);
        else if (strcmp(argv[i], "--threads") == 0 && i + 1 < argc)
            threads = atoi(argv[++i]);
        else if (strcmp(argv[i], "--out") == 0 && i + 1 < argc)
            out_dir = bench_out_dir = argv[++i];
        else if (strcmp(argv[i], "--only") == 0 && i + 1 < argc)
            only = argv[++i];
        else if (strcmp(argv[i], "--shared") == 0 && i + 1 < argc)
            shared_dir = argv[++i];
        else {
            fprintf(stderr, "usage: penumbra_bench [--config FILE] [--runs N] [--threads N] [--out DIR] "
                            "[--only NAME] [--shared DIR]\n");
            return 2;
        }
    }
    if (runs < 1 || runs > MAX_RUNS) {
        fprintf(stderr, "penumbra_bench: --runs must be 1..%d\n", MAX_RUNS);
        return 2;
    }
    bench_case *cases = NULL;
    int count = 0;
    if (!read_config(config, &cases, &count)) return 3;
    mkdir(out_dir, 0777);
    char md_path[1100], json_path[1100];
    snprintf(md_path, sizeof md_path, "%s/latest.md", out_dir);
    snprintf(json_path, sizeof json_path, "%s/latest.json", out_dir);
    FILE *md = fopen(md_path, "w"), *js = fopen(json_path, "w");
    char prog_path[1100];
    snprintf(prog_path, sizeof prog_path, "%s/progressive.md", out_dir);
    FILE *prog = NULL; /* progressive drivers: opened at the first such case */
    if (!md || !js) {
        fprintf(stderr, "penumbra_bench: cannot write into %s: %s\n", out_dir, strerror(errno));
        return 4;
    }
    fprintf(md, "| case | crop | settings | triangles | lights | time median (s) [min, max] | Mrays/s | "
                "shadow rays/px | eye rays/px | peak MiB | relMSE vs pbrt-v4 | Embree share | ias cut + PDF share | "
                "identical runs |\n");
    fprintf(md, "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    fprintf(js, "{\n  \"penumbra\": \"%s\",\n  \"runs\": %d,\n  \"threads\": %d,\n  \"cases\": [", pn_version_string(),
            runs, threads);
    int first = 1;
    int *done_case = malloc((size_t)(count > 0 ? count : 1) * sizeof *done_case);
    bench_result *done = malloc((size_t)(count > 0 ? count : 1) * sizeof *done);
    int done_count = 0;
    if (!done_case || !done) return 4;
    for (int c = 0; c < count; c++) {
        const bench_case *bc = &cases[c];
        if (only && !name_matches(only, bc->name)) continue;
        if (access(bc->scene, R_OK) != 0) {
            fprintf(stderr, "penumbra_bench: %s: skipped (%s not found)\n", bc->name, bc->scene);
            continue;
        }
        int fds[2];
        if (pipe(fds) != 0) return 4;
        fflush(NULL);
        pid_t pid = fork();
        if (pid == 0) {
            close(fds[0]);
            bench_result r;
            run_case(bc, runs, threads, &r);
            ssize_t w = write(fds[1], &r, sizeof r);
            _exit(w == (ssize_t)sizeof r ? 0 : 1);
        }
        close(fds[1]);
        bench_result r;
        memset(&r, 0, sizeof r);
        ssize_t got = read(fds[0], &r, sizeof r);
        close(fds[0]);
        int status = 0;
        waitpid(pid, &status, 0);
        if (got != (ssize_t)sizeof r || !r.ok) {
            fprintf(stderr, "penumbra_bench: %s: failed: %s\n", bc->name,
                    got == (ssize_t)sizeof r ? r.error : "crashed");
            fprintf(md, "| %s | %s | %s | failed: %s ||||||||||\n", bc->name, bc->crop_text, bc->settings_text,
                    r.error);
            continue;
        }
        double px = (double)r.stats.width * (double)r.stats.height;
        double embree_share = r.stats.render_seconds > 0 ? r.stats.embree_seconds_estimate / r.stats.render_seconds : 0;
        /* ias: cluster cuts and PDF upkeep (zero for the reference). */
        double upkeep_share =
            r.stats.render_seconds > 0
                ? (r.stats.cut_seconds_estimate + r.stats.pdf_seconds_estimate) / r.stats.render_seconds
                : 0;
        char relmse[64] = "n/a", relmse_json[64] = "null", rmse_json[64] = "null";
        if (r.has_metrics) {
            snprintf(relmse, sizeof relmse, "%.3g", r.metrics.relmse);
            snprintf(relmse_json, sizeof relmse_json, "%.6g", r.metrics.relmse);
            snprintf(rmse_json, sizeof rmse_json, "%.6g", r.metrics.rmse);
        }
        fprintf(md,
                "| %s | %s | %s | %llu | %u | %.3f [%.3f, %.3f] | %.2f | %.1f | %.1f | %.0f | %s | %.0f%% | %.0f%% | "
                "%s |\n",
                bc->name, bc->crop_text, bc->settings_text, (unsigned long long)r.triangles, r.lights, r.median, r.min,
                r.max, r.stats.mrays_per_second, r.stats.shadow_rays_per_pixel_mean, r.stats.eye_rays_per_pixel_mean,
                (double)r.stats.peak_memory_bytes / 1048576.0, relmse, 100.0 * embree_share, 100.0 * upkeep_share,
                r.bit_identical ? "yes" : "NO");
        fprintf(
            js,
            "%s\n    {\"name\": \"%s\", \"scene\": \"%s\", \"crop\": \"%s\", \"settings\": \"%s\", "
            "\"width\": %d, \"height\": %d, \"pixels\": %.0f, \"triangles\": %llu, \"lights\": %u, "
            "\"parse_seconds\": %.4f, \"bvh_seconds\": %.4f, \"render_seconds_median\": %.4f, "
            "\"render_seconds_min\": %.4f, \"render_seconds_max\": %.4f, \"mrays_per_second\": %.3f, "
            "\"shadow_rays_per_pixel\": %.3f, \"eye_rays_per_pixel\": %.3f, \"peak_memory_bytes\": %llu, "
            "\"embree_share\": %.4f, \"upkeep_share\": %.4f, \"relmse\": %s, \"rmse\": %s, \"bit_identical_runs\": %s}",
            first ? "" : ",", bc->name, bc->scene, bc->crop_text, bc->settings_text, r.stats.width, r.stats.height, px,
            (unsigned long long)r.triangles, r.lights, r.parse_seconds, r.bvh_seconds, r.median, r.min, r.max,
            r.stats.mrays_per_second, r.stats.shadow_rays_per_pixel_mean, r.stats.eye_rays_per_pixel_mean,
            (unsigned long long)r.stats.peak_memory_bytes, embree_share, upkeep_share, relmse_json, rmse_json,
            r.bit_identical ? "true" : "false");
        first = 0;
        done_case[done_count] = c;
        done[done_count++] = r;
        if (r.curve_n > 0) { /* progressive drivers (issue 6) */
            if (!prog && (prog = fopen(prog_path, "w")) != NULL) {
                fprintf(prog, "| case | settings | work pixels %% | rel L1 | rel L2 | time (s) | time / full | full "
                              "render (s) |\n");
                fprintf(prog, "|---|---|---|---|---|---|---|---|\n");
            }
            for (int k = 0; prog && k < r.curve_n; k++)
                fprintf(prog, "| %s | %s | %.2f | %.4f | %.4f | %.2f | %.3f | %.2f |\n", bc->name, bc->settings_text,
                        r.curve_evaluated[k], r.curve_l1[k], r.curve_l2[k], r.curve_seconds[k],
                        r.full_seconds > 0 ? r.curve_seconds[k] / r.full_seconds : 0.0, r.full_seconds);
            for (int k = 0; k < r.curve_n; k++)
                if (r.curve_pct[k] == 6.0)
                    fprintf(stderr, "penumbra_bench: %s: 6%%: L1 %.4f, L2 %.4f, %.2f s (full %.2f s)\n", bc->name,
                            r.curve_l1[k], r.curve_l2[k], r.curve_seconds[k], r.full_seconds);
            if (prog) fflush(prog);
        }
        fprintf(stderr, "penumbra_bench: %s: %.3f s median, relMSE %s\n", bc->name, r.median,
                r.has_metrics ? relmse : "n/a");
    }
    fprintf(js, "\n  ]");
    equal_quality(md, js, cases, done_case, done, done_count);
    fprintf(js, "\n}\n");
    free(done_case);
    free(done);
    fclose(md);
    fclose(js);
    if (prog) fclose(prog);
    free(cases);
    printf("wrote %s and %s\n", md_path, json_path);
    return 0;
}
