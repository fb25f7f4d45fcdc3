/* contour_render.c — the image algorithm of Vedel 1993 §5 around the contour integration of §3
 * (contour.c): the image by scanlines (the default driver's whole-image hook, one job per row),
 * spans of pixels along a row, shaft culling (Haines & Wallace 1991), first-level ray patterns
 * reused along a span with quadratic interpolation in between, adaptive first-level density
 * carried along the row, spans ending at creases, the dichotomy hints of a nearby pixel; and the
 * `contour` / `contour-mc` integrators that shade with it. See contour.c's header for the paper's
 * parts and our departures. With the option contour-trace FILE, the rays of every
 * counted pixel are written to FILE by phase (bench/contour/breakdown.sh): kept in memory while
 * rendering and written atomically (io/write.c) by the finish hook once the render has finished,
 * so a failed or cancelled render leaves no file, and never half of one.
 *
 * Eye rays: a fixed number per pixel (--spp, default 1 as in the paper; the adaptive --threshold
 * mode of the reference does not apply), drawn from the pixel's scrambled Sobol sequence exactly
 * as the reference integrator draws them, so that a contour image and a reference image with
 * --spp 1 see the same points and differ only in their direct light. They are the batch's eye
 * hits (render/batch.h, pn_batch_eye_hits): traced by the driver for render_batch (contour-mc
 * under every driver, contour under the progressive ones); contour's scanline rows
 * (render_image) are batches of its own (pn_batch_part), whose hits the driver's tracers of the
 * window supply. */
#include "integrators/contour_internal.h"
#include "integrators/reference_direct.h"

#include "core/photometry.h"
#include "core/rng.h"
#include "core/threadpool.h"
#include "io/image.h"
#include "render/progress.h"
#include "shade/bsdf.h"
#include "spectral/melanopic.h"
#include "spectral/transport.h"

#include <errno.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PN_CONTOUR_MAX_P 32     /* first-level squares per side, at most */
#define PN_CONTOUR_DISK_QUADS 5 /* a disk is a 12-gon of equal area: 5 quadrilaterals */

/* Our departure (shade_span): a run whose unoccluded form factor at its middle pixel is within
 * the fraction contour-linear-tol (default 0.003, registry.c) of the linear interpolation between
 * its ends is interpolated linearly, without the middle integration (cornell-contour at 800x800,
 * 3x3 fixed, span 64: 11.9 -> 10.0 rays per viewing ray; bench/contour/RESULTS.md). */

typedef struct contour_light {
    int index; /* in job->lights */
    pn_contour_source src;
    vec3 emit;
    vec3 bmin, bmax;
} contour_light;

/* An obstacle for shaft culling: the bounding box of a mesh, sphere or instance; planar meshes
 * only block segments whose ends are strictly on opposite sides of their plane. */
typedef struct obstacle {
    vec3 bmin, bmax;
    bool planar;
    vec3 n;
    float d;
} obstacle;

typedef struct contour_data {
    bool mc;
    contour_light *lights;
    int count;
    unsigned char *skip; /* per scene light: 1 when integrated here */
    obstacle *obstacles;
    int obstacle_count;
    float tol;
    int N, p0;
    FILE *trace;      /* option contour-trace: one line per counted pixel (bench/contour/ray_breakdown.c) */
    char *trace_text; /* the trace's memory stream (open_memstream) */
    size_t trace_size;
    int scout;         /* option contour-scout: the scout lattice, 0-3 (contour.c) */
    int penumbra_part; /* option contour-part: runs with a contour check 1/part of their samples */
    double linear_tol; /* option contour-linear-tol */
    uint32_t off;      /* the PN_CONTOUR_NO_ISLANDS / NO_HALF_CHECK bits of contour_flags, for every evaluation */
    atomic_uint_fast64_t viewing, rays, integrations, interpolated, restarts, subdivisions, culled;
} contour_data;

/* ---- prepare: sources and obstacles --------------------------------------------------------- */

static void box_add(vec3 *bmin, vec3 *bmax, vec3 p) {
    *bmin = v3_min(*bmin, p);
    *bmax = v3_max(*bmax, p);
}

static vec3 mesh_pos(const pn_mesh *m, uint32_t i) {
    return v3(m->positions[3 * (size_t)i], m->positions[3 * (size_t)i + 1], m->positions[3 * (size_t)i + 2]);
}

static void mesh_obstacle(const pn_mesh *m, obstacle *o) {
    o->bmin = v3(INFINITY, INFINITY, INFINITY);
    o->bmax = v3(-INFINITY, -INFINITY, -INFINITY);
    for (uint32_t i = 0; i < m->vertex_count; i++) box_add(&o->bmin, &o->bmax, mesh_pos(m, i));
    o->planar = false;
    float diag = v3_length(v3_sub(o->bmax, o->bmin));
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        const uint32_t *idx = m->indices + 3 * (size_t)t;
        vec3 p0 = mesh_pos(m, idx[0]);
        vec3 n = v3_cross(v3_sub(mesh_pos(m, idx[1]), p0), v3_sub(mesh_pos(m, idx[2]), p0));
        float l = v3_length(n);
        if (!(l > 0.0f)) continue;
        n = v3_scale(n, 1.0f / l);
        bool planar = true;
        for (uint32_t i = 0; i < m->vertex_count && planar; i++)
            planar = fabsf(v3_dot(v3_sub(mesh_pos(m, i), p0), n)) <= 1e-5f * diag;
        if (planar) {
            o->planar = true;
            o->n = n;
            o->d = v3_dot(n, p0);
        }
        break;
    }
}

static void contour_release(pn_render_job *job);

static pn_status contour_prepare_common(pn_render_job *job, pn_err *err, bool mc) {
    const struct pn_scene_s *scene = job->scene;
    const pn_lights *L = job->lights;
    contour_data *cd = calloc(1, sizeof *cd);
    if (!cd) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the contour integrator");
    cd->mc = mc;
    int p0 = (int)job->contour_grid - 1;
    int N = p0 << job->contour_steps;
    if (N > 1024) {
        free(cd);
        return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT,
                          "contour: (grid - 1) * 2^steps = %d exceeds 1024 cells per side of the sample array", N);
    }
    cd->N = N;
    cd->p0 = p0;
    cd->lights = calloc((size_t)L->count * PN_CONTOUR_DISK_QUADS + 1, sizeof *cd->lights);
    cd->skip = calloc((size_t)L->count + 1, 1);
    int obs_cap = scene->mesh_count + scene->sphere_count + scene->instance_count + 1;
    cd->obstacles = calloc((size_t)obs_cap, sizeof *cd->obstacles);
    if (!cd->lights || !cd->skip || !cd->obstacles) {
        free(cd->lights);
        free(cd->skip);
        free(cd->obstacles);
        free(cd);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for the contour integrator");
    }
    /* Planar convex sources: rectangles and triangles (lights.c detects them at load). */
    for (int i = 0; i < L->count; i++) {
        const pn_light *l = &L->lights[i];
        if (l->kind == PN_LIGHT_DISK && l->radius > 0.0f) {
            /* §6: a disk as a regular polygon of 2 + 2 PN_CONTOUR_DISK_QUADS sides and the disk's
             * area, cut into a fan of convex quadrilaterals that share the first vertex. */
            const int sides = 2 + 2 * PN_CONTOUR_DISK_QUADS;
            double r = (double)l->radius *
                       sqrt(2.0 * 3.14159265358979323846 / (sides * sin(2.0 * 3.14159265358979323846 / sides)));
            vec3 t, b, poly[2 + 2 * PN_CONTOUR_DISK_QUADS];
            v3_basis(l->n, &t, &b);
            for (int k = 0; k < sides; k++) {
                double a = 2.0 * 3.14159265358979323846 * k / sides;
                poly[k] = v3_add(l->p, v3_add(v3_scale(t, (float)(r * cos(a))), v3_scale(b, (float)(r * sin(a)))));
            }
            for (int q = 0; q < PN_CONTOUR_DISK_QUADS; q++) {
                contour_light *c = &cd->lights[cd->count++];
                c->index = i;
                c->emit = l->emit;
                vec3 q0 = poly[0], q1 = poly[2 * q + 1], q2 = poly[2 * q + 2], q3 = poly[(2 * q + 3) % sides];
                pn_contour_source_quad(&c->src, q0, q1, q2, q3, l->n, l->two_sided);
                c->bmin = c->bmax = q0;
                box_add(&c->bmin, &c->bmax, q1);
                box_add(&c->bmin, &c->bmax, q2);
                box_add(&c->bmin, &c->bmax, q3);
            }
            cd->skip[i] = 1;
            continue;
        }
        if (l->kind != PN_LIGHT_RECTANGLE && l->kind != PN_LIGHT_TRIANGLE) continue;
        contour_light *c = &cd->lights[cd->count++];
        c->index = i;
        c->emit = l->emit;
        if (l->kind == PN_LIGHT_RECTANGLE)
            pn_contour_source_rectangle(&c->src, l->p, l->e1, l->e2, l->n, l->two_sided);
        else
            pn_contour_source_triangle(&c->src, l->p, v3_add(l->p, l->e1), v3_add(l->p, l->e2), l->n, l->two_sided);
        c->bmin = c->bmax = l->p;
        box_add(&c->bmin, &c->bmax, v3_add(l->p, l->e1));
        box_add(&c->bmin, &c->bmax, v3_add(l->p, l->e2));
        if (l->kind == PN_LIGHT_RECTANGLE) box_add(&c->bmin, &c->bmax, v3_add(v3_add(l->p, l->e1), l->e2));
        cd->skip[i] = 1;
    }
    /* Obstacles: world meshes and spheres, and instances as the box of their object. */
    for (int i = 0; i < scene->mesh_count; i++) {
        const pn_mesh *m = &scene->meshes[i];
        if (m->object >= 0 || m->triangle_count == 0) continue;
        mesh_obstacle(m, &cd->obstacles[cd->obstacle_count++]);
    }
    for (int i = 0; i < scene->sphere_count; i++) {
        const pn_sphere *s = &scene->spheres[i];
        if (s->object >= 0) continue;
        obstacle *o = &cd->obstacles[cd->obstacle_count++];
        vec3 r = v3(s->radius, s->radius, s->radius);
        o->bmin = v3_sub(s->center, r);
        o->bmax = v3_add(s->center, r);
        o->planar = false;
    }
    for (int i = 0; i < scene->instance_count; i++) {
        const pn_instance *in = &scene->instances[i];
        const pn_object *ob = &scene->objects[in->object];
        vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
        for (int k = 0; k < ob->mesh_count; k++) {
            obstacle t;
            mesh_obstacle(&scene->meshes[ob->first_mesh + k], &t);
            if (!(t.bmin.x <= t.bmax.x)) continue;
            box_add(&lo, &hi, t.bmin);
            box_add(&lo, &hi, t.bmax);
        }
        for (int k = 0; k < ob->sphere_count; k++) {
            const pn_sphere *s = &scene->spheres[ob->first_sphere + k];
            vec3 r = v3(s->radius, s->radius, s->radius);
            box_add(&lo, &hi, v3_sub(s->center, r));
            box_add(&lo, &hi, v3_add(s->center, r));
        }
        if (!(lo.x <= hi.x)) continue;
        obstacle *o = &cd->obstacles[cd->obstacle_count++];
        o->bmin = v3(INFINITY, INFINITY, INFINITY);
        o->bmax = v3(-INFINITY, -INFINITY, -INFINITY);
        for (int c = 0; c < 8; c++) {
            vec3 p = v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
            box_add(&o->bmin, &o->bmax, mat4_apply_point(&in->world_from_object, p));
        }
        o->planar = false;
    }
    vec3 ext = v3_sub(scene->bounds_max, scene->bounds_min);
    /* Above the ray epsilon (at most 1e-4 of the diagonal), by which span boxes are padded. */
    cd->tol = 2e-4f * (v3_is_finite(ext) ? v3_length(ext) : 1.0f);
    atomic_init(&cd->viewing, 0);
    atomic_init(&cd->rays, 0);
    atomic_init(&cd->integrations, 0);
    atomic_init(&cd->interpolated, 0);
    atomic_init(&cd->restarts, 0);
    atomic_init(&cd->subdivisions, 0);
    atomic_init(&cd->culled, 0);
    /* Bench instrumentation (option contour-trace): where the shadow rays go, per pixel. */
    if (job->contour_trace && *job->contour_trace) {
        cd->trace = open_memstream(&cd->trace_text, &cd->trace_size);
        if (!cd->trace) {
            job->integrator_data = cd;
            contour_release(job);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for the contour trace",
                              job->contour_trace);
        }
    }
    /* Our departures are switched off by contour_flags (contour-off islands,half,scouts,linear).
     * Tuning options for the bench (bench/contour/RESULTS.md): contour-scout 0..3, the scout
     * probes (contour.c: 0; 1: 4 points, the centres of the 3 x 3 grid's squares; 2: 16; 3: 49, the
     * inner points of an 8 x 8 lattice), by default (-1) 3 with a fixed first-level density and 1
     * with the adaptive one (with the adaptive density 3 costs up to twice the rays on hall-many
     * for a small gain); contour-part 1, 2 or 4: runs with a contour check 1 / part of their
     * samples from their third pixel on; contour-linear-tol: the tolerance of run_is_linear. */
    cd->off = job->contour_flags & (PN_CONTOUR_NO_ISLANDS | PN_CONTOUR_NO_HALF_CHECK);
    cd->scout = (job->contour_flags & PN_CONTOUR_NO_SCOUTS)             ? 0
                : (job->contour_flags & PN_CONTOUR_NO_ADAPTIVE_DENSITY) ? 3
                                                                        : 1;
    if (job->contour_scout >= 0 && !(job->contour_flags & PN_CONTOUR_NO_SCOUTS)) cd->scout = job->contour_scout;
    cd->penumbra_part = job->contour_part == 1 || job->contour_part == 4 ? job->contour_part : 2;
    cd->linear_tol = (job->contour_flags & PN_CONTOUR_NO_LINEAR_RUNS) ? 0.0 : job->contour_linear_tol;
    job->integrator_data = cd;
    return PN_OK;
}

static pn_status contour_prepare(pn_render_job *job, pn_err *err) {
    return contour_prepare_common(job, err, false);
}
static pn_status contour_mc_prepare(pn_render_job *job, pn_err *err) {
    return contour_prepare_common(job, err, true);
}

static void contour_release(pn_render_job *job) {
    contour_data *cd = job->integrator_data;
    if (!cd) return;
    if (cd->trace) fclose(cd->trace);
    free(cd->trace_text);
    free(cd->lights);
    free(cd->skip);
    free(cd->obstacles);
    free(cd);
    job->integrator_data = NULL;
}

static pn_status write_trace_to(void *user, FILE *file, const char *path, pn_err *err) {
    const contour_data *cd = user;
    if (cd->trace_size > 0 && fwrite(cd->trace_text, 1, cd->trace_size, file) != cd->trace_size)
        return pn_err_set(err, PN_ERROR_IO, "%s: %s", path, strerror(errno));
    return PN_OK;
}

/* After a finished render: the trace, whole, in one atomic write. */
static pn_status contour_finish(pn_render_job *job, pn_err *err) {
    contour_data *cd = job->integrator_data;
    if (!cd || !cd->trace) return PN_OK;
    if (fflush(cd->trace) != 0) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", job->contour_trace);
    return pn_write_atomic(job->contour_trace, write_trace_to, cd, err);
}

static void contour_report(const pn_render_job *job, pn_render_stats *stats) {
    contour_data *cd = job->integrator_data;
    if (!cd) return;
    stats->contour_viewing_rays = atomic_load(&cd->viewing);
    stats->contour_shadow_rays = atomic_load(&cd->rays);
    stats->contour_integrations = atomic_load(&cd->integrations);
    stats->contour_interpolated = atomic_load(&cd->interpolated);
    stats->contour_restarts = atomic_load(&cd->restarts);
    stats->contour_subdivisions = atomic_load(&cd->subdivisions);
    stats->contour_culled_spans = atomic_load(&cd->culled);
}

/* ---- shaft culling (Haines & Wallace 1991) -------------------------------------------------- */

static float coord(vec3 v, int a) {
    return v3_get(v, a);
}

/* 2D convex hull (monotone chain) of n <= 8 points, counter-clockwise; returns its size. */
static int hull2d(float (*pt)[2], int n, float (*out)[2]) {
    for (int i = 1; i < n; i++) /* insertion sort by x, then y */
        for (int j = i; j > 0 && (pt[j][0] < pt[j - 1][0] || (pt[j][0] == pt[j - 1][0] && pt[j][1] < pt[j - 1][1]));
             j--) {
            float t0 = pt[j][0], t1 = pt[j][1];
            pt[j][0] = pt[j - 1][0];
            pt[j][1] = pt[j - 1][1];
            pt[j - 1][0] = t0;
            pt[j - 1][1] = t1;
        }
    int k = 0;
    for (int pass = 0; pass < 2; pass++) {
        int start = k;
        for (int ii = 0; ii < n; ii++) {
            int i = pass == 0 ? ii : n - 1 - ii;
            while (k >= start + 2) {
                float cr = (out[k - 1][0] - out[k - 2][0]) * (pt[i][1] - out[k - 2][1]) -
                           (out[k - 1][1] - out[k - 2][1]) * (pt[i][0] - out[k - 2][0]);
                if (cr > 0.0f) break;
                k--;
            }
            out[k][0] = pt[i][0];
            out[k][1] = pt[i][1];
            k++;
        }
        k--; /* the last point of each chain starts the other */
    }
    return k;
}

/* True when the obstacle's box may intersect the shaft between boxes a and b: it overlaps
 * their joint box and no projection on a coordinate plane separates it from the hull of their
 * projections (the shaft's planes of Haines & Wallace). */
static bool shaft_candidate(const obstacle *o, vec3 amin, vec3 amax, vec3 bmin, vec3 bmax, float tol) {
    if (o->planar) {
        /* A plane blocks only segments that cross it. */
        float a_lo = INFINITY, a_hi = -INFINITY, b_lo = INFINITY, b_hi = -INFINITY;
        for (int c = 0; c < 8; c++) {
            vec3 pa = v3(c & 1 ? amax.x : amin.x, c & 2 ? amax.y : amin.y, c & 4 ? amax.z : amin.z);
            vec3 pb = v3(c & 1 ? bmax.x : bmin.x, c & 2 ? bmax.y : bmin.y, c & 4 ? bmax.z : bmin.z);
            float da = v3_dot(o->n, pa) - o->d, db = v3_dot(o->n, pb) - o->d;
            a_lo = fminf(a_lo, da);
            a_hi = fmaxf(a_hi, da);
            b_lo = fminf(b_lo, db);
            b_hi = fmaxf(b_hi, db);
        }
        if (!((a_lo < -tol && b_hi > tol) || (a_hi > tol && b_lo < -tol))) return false;
    }
    vec3 umin = v3_min(amin, bmin), umax = v3_max(amax, bmax);
    for (int a = 0; a < 3; a++)
        if (coord(o->bmax, a) < coord(umin, a) - tol || coord(o->bmin, a) > coord(umax, a) + tol) return false;
    for (int drop = 0; drop < 3; drop++) {
        int x = (drop + 1) % 3, y = (drop + 2) % 3;
        float pts[8][2], hull[18][2];
        for (int c = 0; c < 4; c++) {
            pts[c][0] = c & 1 ? coord(amax, x) : coord(amin, x);
            pts[c][1] = c & 2 ? coord(amax, y) : coord(amin, y);
            pts[4 + c][0] = c & 1 ? coord(bmax, x) : coord(bmin, x);
            pts[4 + c][1] = c & 2 ? coord(bmax, y) : coord(bmin, y);
        }
        int h = hull2d(pts, 8, hull);
        if (h < 3) continue;
        for (int e = 0; e < h; e++) {
            float ex = hull[(e + 1) % h][0] - hull[e][0], ey = hull[(e + 1) % h][1] - hull[e][1];
            float len = sqrtf(ex * ex + ey * ey);
            if (!(len > 0.0f)) continue;
            float nx = ey / len, ny = -ex / len; /* outward for a counter-clockwise hull */
            bool all_out = true;
            for (int c = 0; c < 4 && all_out; c++) {
                float px = c & 1 ? coord(o->bmax, x) : coord(o->bmin, x);
                float py = c & 2 ? coord(o->bmax, y) : coord(o->bmin, y);
                all_out = (px - hull[e][0]) * nx + (py - hull[e][1]) * ny > tol;
            }
            if (all_out) return false;
        }
    }
    return true;
}

static bool shaft_has_candidates(const contour_data *cd, const contour_light *cl, vec3 smin, vec3 smax) {
    for (int i = 0; i < cd->obstacle_count; i++)
        if (shaft_candidate(&cd->obstacles[i], smin, smax, cl->bmin, cl->bmax, cd->tol)) return true;
    return false;
}

/* ---- per-batch state ------------------------------------------------------------------------- */

typedef struct shade_point {
    bool has_point, diffuse;
    pn_hit hit;
    vec3 wo, throughput;
    pn_bsdf b;
    pn_swl wl;     /* spectral mode: this eye ray's wavelengths (b.wl points here); else off */
    vec3 value;    /* this eye ray's radiance so far */
    vec3 gradient; /* this eye ray's irradiance-luminance gradient from contour lights */
    double lux;    /* PN_AOV_ILLUMINANCE: this eye ray's direct illuminance (lx, white receiver) */
    double mel;    /* PN_AOV_MELANOPIC_EDI: its melanopic EDI (lx, spectral mode, at wl) */
    uint32_t contour_rays;
    uint32_t rays_by[PN_CPH_COUNT], visible_rays; /* trace: rays by phase, visible ones */
    unsigned why;                                 /* trace: bit r set when integrated for reason r (WHY_*) */
    bool culled;                                  /* trace: a span of this pixel had no candidate obstacle */
    float fw;
    int64_t object; /* what a span must stay on */
} shade_point;

typedef struct pixel_acc {
    vec3 weighted_sum, gradient_sum;
    double weight_sum, lum_mean, lum_m2;
    double weighted_lux; /* PN_AOV_ILLUMINANCE: filter-weighted illuminance of the eye rays */
    double weighted_mel; /* PN_AOV_MELANOPIC_EDI: the same for the melanopic EDI */
    uint32_t n, shadow_rays, specular_rays;
    uint32_t non_finite; /* eye rays whose value was not finite, counted as 0 */
} pixel_acc;

typedef struct contour_scratch {
    pn_reference_direct_scratch ref;
    int capacity;
    shade_point *sp;
    pixel_acc *acc;
    uint32_t *scramble;
    size_t array_size;  /* (N+1)^2 */
    int span_capacity;  /* pixels of the longest span the arrays below hold */
    uint8_t *vis;       /* one sample array per pixel of the span */
    uint8_t *glazed;    /* glazing (contour.c): per pixel, its samples seen through thin glass */
    uint8_t *vis_clear; /* glazing: the clear pass's sample array (one integration at a time) */
    float *thit;
    pn_contour_eval *ev;
    pn_contour_g *g;
    int *span; /* batch indices of the current span */
    /* Along the row, for the contour light being shaded (lights are shaded one after another,
     * each over the whole row): */
    int density;    /* first-level squares per side where the last span ended */
    uint8_t *carry; /* the sample array of the last pixel integrated */
    int carry_x;    /* its image x (INT32_MIN: none) */
} contour_scratch;

static void contour_scratch_free(void *p) {
    contour_scratch *s = p;
    if (!s) return;
    pn_reference_direct_free(&s->ref);
    free(s->sp);
    free(s->acc);
    free(s->scramble);
    free(s->vis);
    free(s->glazed);
    free(s->vis_clear);
    free(s->thit);
    free(s->ev);
    free(s->g);
    free(s->span);
    free(s->carry);
    free(s);
}

static void *contour_scratch_create(const pn_render_job *job) {
    const contour_data *cd = job->integrator_data;
    contour_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    if (!pn_reference_direct_init(&s->ref, job)) {
        free(s);
        return NULL;
    }
    s->array_size = (size_t)(cd->N + 1) * (size_t)(cd->N + 1);
    s->carry = malloc(s->array_size);
    if (!s->carry) {
        contour_scratch_free(s);
        return NULL;
    }
    return s;
}

/* Room for spans of up to n pixels: one sample array per pixel (grown on demand, as a span may
 * now run along a whole scanline). */
static bool ensure_span_capacity(contour_scratch *s, const pn_render_job *job, int n) {
    if (n <= s->span_capacity) return true;
    const bool gradient = (job->aovs & PN_AOV_GRADIENT) != 0;
    free(s->vis);
    free(s->glazed);
    free(s->vis_clear);
    free(s->thit);
    free(s->ev);
    free(s->g);
    free(s->span);
    /* Glazing's arrays only when thin glass passes the rays. */
    const bool glazing = !job->opaque_glass && pn_accel_has_thin_glass(job->accel);
    s->glazed = glazing ? malloc(s->array_size * (size_t)n) : NULL;
    s->vis_clear = glazing ? malloc(s->array_size) : NULL;
    s->vis = malloc(s->array_size * (size_t)n);
    s->thit = gradient ? malloc(s->array_size * (size_t)n * sizeof *s->thit) : NULL;
    s->ev = malloc((size_t)n * sizeof *s->ev);
    s->g = malloc((size_t)n * sizeof *s->g);
    s->span = malloc((size_t)n * sizeof *s->span);
    s->span_capacity =
        (s->vis && s->ev && s->g && s->span && (!gradient || s->thit) && (!glazing || (s->glazed && s->vis_clear))) ? n
                                                                                                                    : 0;
    return s->span_capacity > 0;
}

static bool ensure_capacity(contour_scratch *s, int count) {
    if (count <= s->capacity) return true;
    free(s->sp);
    free(s->acc);
    free(s->scramble);
    s->sp = malloc((size_t)count * sizeof *s->sp);
    s->acc = malloc((size_t)count * sizeof *s->acc);
    s->scramble = malloc((size_t)count * sizeof *s->scramble);
    s->capacity = (s->sp && s->acc && s->scramble) ? count : 0;
    return s->capacity > 0;
}

/* ---- §5: spans ------------------------------------------------------------------------------- */

static void zero_g(pn_contour_g *g) {
    *g = (pn_contour_g){{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
}

static pn_dvec3 lagrange3(pn_dvec3 a, pn_dvec3 b, pn_dvec3 c, double wa, double wb, double wc) {
    return pn_dv3_add(pn_dv3_add(pn_dv3_scale(a, wa), pn_dv3_scale(b, wb)), pn_dv3_scale(c, wc));
}

/* Tallies of one span, added to the render's statistics by the caller. */
typedef struct span_tally {
    uint64_t integrations, interpolated, restarts, subdivisions, culled;
} span_tally;

typedef struct span_ctx {
    const pn_render_job *job;
    const contour_data *cd;
    const contour_light *cl;
    contour_scratch *s;
    int n;
    span_tally t;
    int *density; /* the first-level density carried from span to span along the row */
    int x0;       /* image x of the span's first pixel (span pixels are adjacent) */
    uint8_t *carry;
    int *carry_x;
} span_ctx;

/* Our departure (contour.c's header): integrations take the crossings of a pixel integrated before,
 * at most this many pixels away along the row, as the first guess of their dichotomies. */
#define PN_CONTOUR_HINT_DISTANCE 8

/* Spans end where the shading normal turns by more than about 25 degrees between two pixels (a
 * crease of one mesh: a box's edge, a wall meeting the floor): G interpolated from one face is
 * wrong on the other, where other parts of the source are above the horizon. */
#define PN_CONTOUR_SPAN_CREASE_COS 0.9f

/* Why a pixel gets a full integration (trace statistics). */
enum { WHY_START, WHY_CHANGE, WHY_MIDDLE, WHY_UNIFORM, WHY_EVERY, WHY_COUNT };

/* Full approximate contour integration at span pixel q with p first-level squares per side. */
static void full_integration(span_ctx *sc, int q, int p, int why) {
    pn_contour_eval *ev = &sc->s->ev[q];
    ev->why |= 1 << why;
    /* The hint for its dichotomies: the nearest pixel of the span integrated before it, or the
     * last one integrated in the row before the span, at most PN_CONTOUR_HINT_DISTANCE away. */
    ev->hint = NULL;
    int best = -1;
    for (int k = 0; k < sc->n; k++)
        if (k != q && sc->s->ev[k].why && (best < 0 || abs(k - q) < abs(best - q))) best = k;
    if (best >= 0 && abs(best - q) <= PN_CONTOUR_HINT_DISTANCE)
        ev->hint = sc->s->vis + (size_t)best * sc->s->array_size;
    int cx = *sc->carry_x;
    if (cx != INT32_MIN && sc->x0 + q - cx <= PN_CONTOUR_HINT_DISTANCE && (best < 0 || sc->x0 + q - cx < abs(best - q)))
        ev->hint = sc->carry;
    /* Our departure (contour.c): scouts, and probes where the hint pixel found islands (no
     * scouts in uniform runs: there the pattern check decides). */
    ev->scout = why == WHY_UNIFORM ? 0 : sc->cd->scout;
    pn_contour_probe_islands(ev, ev->hint, p);
    pn_contour_integrate(ev, p);
    sc->s->g[q] = ev->acc;
    sc->t.integrations++;
}

void pn_contour_pattern_boundary(const uint8_t *pattern, int p, uint8_t *mask) {
    for (int b = 0; b <= p; b++)
        for (int a = 0; a <= p; a++) {
            int k = b * (p + 1) + a;
            uint8_t x = pattern[k];
            mask[k] = (a > 0 && pattern[k - 1] != x) || (a < p && pattern[k + 1] != x) ||
                      (b > 0 && pattern[k - p - 1] != x) || (b < p && pattern[k + p + 1] != x);
        }
}

/* First-level pattern of pixel q at density p (traces the rays not yet traced). */
static void first_level_pattern(span_ctx *sc, int q, int p, uint8_t *pattern) {
    pn_contour_eval *ev = &sc->s->ev[q];
    int step = ev->N / p;
    ev->phase = PN_CPH_PATTERN;
    for (int b = 0, k = 0; b <= p; b++)
        for (int a = 0; a <= p; a++, k++) pattern[k] = pn_contour_sample_class(ev, a * step, b * step);
}

/* G at span pixel q from the quadratic through the full integrations at a < m < b. */
static pn_contour_g quadratic_g(const contour_scratch *s, int a, int m, int b, int q) {
    double x0 = a, x1 = m, x2 = b, x = q;
    double w0 = (x - x1) * (x - x2) / ((x0 - x1) * (x0 - x2));
    double w1 = (x - x0) * (x - x2) / ((x1 - x0) * (x1 - x2));
    double w2 = (x - x0) * (x - x1) / ((x2 - x0) * (x2 - x1));
    pn_contour_g g;
    g.g = lagrange3(s->g[a].g, s->g[m].g, s->g[b].g, w0, w1, w2);
    for (int k = 0; k < 3; k++) g.dg[k] = lagrange3(s->g[a].dg[k], s->g[m].dg[k], s->g[b].dg[k], w0, w1, w2);
    return g;
}

/* The pixels strictly between a and b, with full integrations at a, m and b, get G by quadratic
 * interpolation (§5). (Branch contour-spans checked runs over 8 pixels with two more
 * integrations; with spans ending at creases it no longer paid: bench/contour/RESULTS.md.) */
static void interpolate_run(span_ctx *sc, int a, int m, int b) {
    contour_scratch *s = sc->s;
    for (int q = a + 1; q < b; q++) {
        if (q == m) continue;
        s->g[q] = quadratic_g(s, a, m, b, q);
        sc->t.interpolated++;
    }
}

/* (contour_internal.h) */
bool pn_contour_run_is_linear(const pn_contour_source *src, const pn_contour_eval *a, const pn_contour_eval *m,
                              const pn_contour_eval *b, double w, double tol) {
    const pn_contour_eval *at[3] = {a, m, b};
    double fu[3];
    for (int k = 0; k < 3; k++) {
        pn_contour_g g;
        pn_contour_source_unoccluded(src, at[k]->m, at[k]->ns, at[k]->ng, false, &g);
        fu[k] = pn_dv3_dot(g.g, at[k]->ns);
    }
    return fabs(fu[1] - ((1.0 - w) * fu[0] + w * fu[2])) <= tol * fabs(fu[1]);
}

/* Our departure (shade_span): runs check part of their first-level samples from this many pixels
 * after their first on (half; option contour-part), and uniform runs a quarter from the second. */
#define PN_CONTOUR_UNIFORM_HALF_AFTER 2
#define PN_CONTOUR_UNIFORM_QUARTER_AFTER 6

/* Whether pixel j's first-level samples (those of mask; with part = 2 or 4 only the samples (a, b)
 * with a + (part / 2) b = x modulo part: a checkerboard or a quarter that moves with the pixel's
 * x) match the pattern at density p; traces what it checks. */
static bool check_pattern(contour_scratch *s, int j, int p, const uint8_t *pattern, const uint8_t *mask, int part,
                          int x) {
    pn_contour_eval *ej = &s->ev[j];
    const int step = ej->N / p, np = (p + 1) * (p + 1);
    ej->phase = PN_CPH_PATTERN;
    for (int k = 0; k < np; k++) {
        int a = k % (p + 1), b = k / (p + 1);
        if (!mask[k] || (part > 1 && ((a + (part / 2) * b - x) % part + part) % part != 0)) continue;
        if (pn_contour_sample_class(ej, a * step, b * step) != pattern[k]) return false;
    }
    return true;
}

static void shade_span(span_ctx *sc) {
    const contour_data *cd = sc->cd;
    const int n = sc->n;
    contour_scratch *s = sc->s;
    const uint32_t flags = sc->job->contour_flags;
    if (cd->mc) {
        for (int q = 0; q < n; q++) {
            zero_g(&s->g[q]);
            double f = pn_contour_mc_form_factor(&s->ev[q], cd->p0, sc->job->contour_mc_threshold,
                                                 sc->job->contour_mc_max_rays);
            /* A scalar estimate: as a G along the receiver's normal. */
            s->g[q].g = pn_dv3_scale(s->ev[q].ns, f);
        }
        return;
    }
    int p = *sc->density;
    /* Raised density: at most twice the initial one per side (9 -> 25 samples by default). */
    int pmax = 2 * cd->p0;
    if (pmax > cd->N) pmax = cd->N;
    if (pmax > PN_CONTOUR_MAX_P) pmax = PN_CONTOUR_MAX_P;
    uint8_t key_pattern[(PN_CONTOUR_MAX_P + 1) * (PN_CONTOUR_MAX_P + 1)];
    int key = 0;
    full_integration(sc, key, p, WHY_START);
    for (;;) {
        /* The density adapts to what the last full integration at a run's start needed. */
        const pn_contour_eval *ev = &s->ev[key];
        if (!(flags & PN_CONTOUR_NO_ADAPTIVE_DENSITY)) {
            if ((ev->restarted || ev->max_depth >= 2) && p < pmax) {
                p *= 2;
                if (ev->p_used > p) p = ev->p_used < pmax ? ev->p_used : pmax;
            } else if (ev->max_depth == 0 && p > cd->p0) {
                p /= 2;
            }
        }
        if (key + 1 >= n) break;
        if (flags & PN_CONTOUR_NO_SPANS) {
            full_integration(sc, ++key, p, WHY_EVERY);
            continue;
        }
        /* Only first-level rays at the next pixels, while their pattern stays the same. */
        first_level_pattern(sc, key, p, key_pattern);
        const int np = (p + 1) * (p + 1);
        bool uniform = true;
        for (int k = 1; k < np; k++) uniform = uniform && key_pattern[k] == key_pattern[0];
        int j = key + 1;
        /* Our departure: only the samples next to a sample of the other visibility in the run's
         * pattern (where a moving contour changes the pattern first) are checked, unless the
         * pattern is uniform (then all are). */
        uint8_t mask[(PN_CONTOUR_MAX_P + 1) * (PN_CONTOUR_MAX_P + 1)];
        if (!uniform)
            pn_contour_pattern_boundary(key_pattern, p, mask);
        else
            memset(mask, 1, (size_t)np);
        for (; j < n; j++) {
            /* Our departure: from a run's third pixel on, each pixel checks part of the samples
             * (half, moving with x; in a uniform run a quarter from its sixth pixel); where the
             * part differs, the pixels before it checked in part are checked in full back to the
             * last that matches, so the run ends where a full check would end it. */
            int part = 1;
            if (uniform && !(sc->cd->off & PN_CONTOUR_NO_HALF_CHECK))
                part = j - key >= PN_CONTOUR_UNIFORM_QUARTER_AFTER ? 4
                       : j - key >= PN_CONTOUR_UNIFORM_HALF_AFTER  ? 2
                                                                   : 1;
            else if (!uniform && sc->cd->penumbra_part > 1 && j - key >= PN_CONTOUR_UNIFORM_HALF_AFTER)
                part = sc->cd->penumbra_part;
            bool same = check_pattern(s, j, p, key_pattern, mask, part, sc->x0 + j);
            if (!same) {
                /* The pixels before it checked in part: completed, back to the last that matches. */
                for (int b = j - 1; b > key && s->ev[b].partial; b--) {
                    if (check_pattern(s, b, p, key_pattern, mask, 1, 0)) {
                        s->ev[b].partial = false;
                        break;
                    }
                    j = b;
                }
                break;
            }
            s->ev[j].partial = part > 1;
        }
        if (uniform) {
            /* Every first-level sample visible (or every one hidden): an integration traces no
             * more rays, so each pixel of the run gets its own; a pixel checked by half gets the
             * closed form of the whole source (visible) or nothing (hidden), which is what that
             * integration would give. */
            for (int q = key + 1; q < j; q++) {
                /* Glazing: a pattern seen through a pane is integrated (its edge may be near). */
                if (!s->ev[q].partial || (key_pattern[0] & 2u)) {
                    full_integration(sc, q, p, WHY_UNIFORM);
                } else if (key_pattern[0]) {
                    const pn_contour_eval *eq = &s->ev[q];
                    pn_contour_source_unoccluded(&sc->cl->src, eq->m, eq->ns, eq->ng,
                                                 (sc->job->aovs & PN_AOV_GRADIENT) != 0, &s->g[q]);
                    sc->t.interpolated++;
                } else {
                    zero_g(&s->g[q]);
                    sc->t.interpolated++;
                }
            }
            if (j >= n) break;
            full_integration(sc, j, p, WHY_CHANGE);
            key = j;
            continue;
        }
        /* The run ends where the pattern changed (that pixel opens the next run) or at the end
         * of the span; the pixels in between are interpolated with a third integration in the
         * middle. */
        int end = j < n ? j : n - 1;
        if (end > key) full_integration(sc, end, p, WHY_CHANGE);
        /* Our departure: when the unoccluded form factor is linear along the run to within
         * contour-linear-tol at its middle, the run is interpolated linearly between its ends
         * without the middle integration (run_is_linear()). */
        const bool linear =
            end - key >= 2 && sc->cd->linear_tol > 0.0 &&
            pn_contour_run_is_linear(&sc->cl->src, &s->ev[key], &s->ev[(key + end) / 2], &s->ev[end],
                                     (double)((key + end) / 2 - key) / (double)(end - key), sc->cd->linear_tol);
        if (linear) {
            for (int q = key + 1; q < end; q++) {
                double w = (double)(q - key) / (double)(end - key);
                s->g[q].g = pn_dv3_add(pn_dv3_scale(s->g[key].g, 1.0 - w), pn_dv3_scale(s->g[end].g, w));
                for (int k = 0; k < 3; k++)
                    s->g[q].dg[k] =
                        pn_dv3_add(pn_dv3_scale(s->g[key].dg[k], 1.0 - w), pn_dv3_scale(s->g[end].dg[k], w));
                sc->t.interpolated++;
            }
        } else if (end - key >= 2) {
            int mid = (key + end) / 2;
            full_integration(sc, mid, p, WHY_MIDDLE);
            interpolate_run(sc, key, mid, end);
        }
        if (j >= n) break;
        key = j;
    }
    *sc->density = p;
    for (int q = n - 1; q >= 0; q--)
        if (s->ev[q].why) {
            memcpy(sc->carry, s->vis + (size_t)q * s->array_size, s->array_size);
            *sc->carry_x = sc->x0 + q;
            break;
        }
    for (int q = 0; q < n; q++) {
        sc->t.restarts += s->ev[q].restarts;
        sc->t.subdivisions += s->ev[q].subdivisions;
    }
}

/* ---- the integrator --------------------------------------------------------------------------- */

static int64_t object_key(const pn_hit *h) {
    return ((int64_t)h->instance + 1) * ((int64_t)1 << 40) + ((int64_t)h->mesh + 1) * ((int64_t)1 << 20) +
           (int64_t)h->sphere + 1;
}

/* Shades the contour lights for eye ray i of every pixel of the batch. */
static void shade_contour_lights(const pn_render_job *job, const contour_data *cd, const pn_batch *batch,
                                 contour_scratch *s, uint32_t eye_index, span_tally *tally) {
    const bool gradient = (job->aovs & PN_AOV_GRADIENT) != 0;
    const bool lux = (job->aovs & PN_AOV_ILLUMINANCE) != 0;
    const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) != 0 && job->spectral;
    const int span_max = (int)job->contour_span;
    for (int li = 0; li < cd->count; li++) {
        const contour_light *cl = &cd->lights[li];
        /* The first-level density adapts along the whole row (batch), not span by span: a span
         * that restarted at the initial density made 8-pixel blocks at span 8. */
        s->density = cd->p0;
        s->carry_x = INT32_MIN;
        int q = 0;
        while (q < batch->count) {
            /* A span: adjacent pixels of a row on the same object that see the source. */
            int n = 0;
            vec3 smin = v3(INFINITY, INFINITY, INFINITY), smax = v3(-INFINITY, -INFINITY, -INFINITY);
            for (; q < batch->count && n < span_max; q++) {
                shade_point *sp = &s->sp[q];
                if (!sp->has_point || !sp->diffuse) {
                    if (n > 0) break;
                    continue;
                }
                if (n > 0) {
                    const shade_point *prev = &s->sp[s->span[n - 1]];
                    int pq = s->span[n - 1];
                    /* Spans also end at multiples of the maximum length in full-image x, so that
                     * they do not depend on where a crop window or a batch begins. */
                    if (batch->pixels[q][1] != batch->pixels[pq][1] ||
                        batch->pixels[q][0] != batch->pixels[pq][0] + 1 || sp->object != prev->object ||
                        batch->pixels[q][0] % span_max == 0 ||
                        v3_dot(sp->b.ns, prev->b.ns) < PN_CONTOUR_SPAN_CREASE_COS)
                        break;
                }
                pn_contour_eval *ev = &s->ev[n];
                uint8_t *vis = s->vis + (size_t)n * s->array_size;
                memset(vis, 0, s->array_size);
                float *thit = s->thit ? s->thit + (size_t)n * s->array_size : NULL;
                uint64_t hash = pn_hash3(
                    job->seed ^ (uint64_t)li,
                    ((uint64_t)(uint32_t)batch->pixels[q][0] << 32) | (uint32_t)batch->pixels[q][1], eye_index);
                if (!pn_contour_eval_setup(ev, job, &cl->src, sp->hit.p, sp->b.ns, sp->b.ng, cd->N, vis, thit, gradient,
                                           hash)) {
                    if (n > 0) {
                        q++;
                        break;
                    }
                    continue;
                }
                ev->flags |= cd->off;
                if (s->glazed) {
                    uint8_t *glazed = s->glazed + (size_t)n * s->array_size;
                    memset(glazed, 0, s->array_size);
                    pn_contour_eval_set_glazing(ev, glazed, s->vis_clear);
                }
                s->span[n++] = q;
                box_add(&smin, &smax, v3_sub(sp->hit.p, v3(ev->eps, ev->eps, ev->eps)));
                box_add(&smin, &smax, v3_add(sp->hit.p, v3(ev->eps, ev->eps, ev->eps)));
            }
            if (n == 0) continue;
            span_ctx sc = {job,      cd,         cl, s, n, {0, 0, 0, 0, 0}, &s->density, batch->pixels[s->span[0]][0],
                           s->carry, &s->carry_x};
            if (!(job->contour_flags & PN_CONTOUR_NO_SHAFT_CULLING) && !shaft_has_candidates(cd, cl, smin, smax)) {
                /* Empty candidate list: the unoccluded closed form, no shadow rays. */
                for (int k = 0; k < n; k++) {
                    const pn_contour_eval *ev = &s->ev[k];
                    pn_contour_source_unoccluded(&cl->src, ev->m, ev->ns, ev->ng, gradient, &s->g[k]);
                }
                sc.t.culled++;
                for (int k = 0; k < n; k++) s->sp[s->span[k]].culled = true;
            } else {
                shade_span(&sc);
            }
            tally->integrations += sc.t.integrations;
            tally->interpolated += sc.t.interpolated;
            tally->restarts += sc.t.restarts;
            tally->subdivisions += sc.t.subdivisions;
            tally->culled += sc.t.culled;
            /* L_o = kd L F for a diffuse receiver; G projected on the pixel's own normal. */
            for (int k = 0; k < n; k++) {
                shade_point *sp = &s->sp[s->span[k]];
                pn_dvec3 ns = pn_dv3_from(sp->b.ns);
                double f = pn_dv3_dot(s->g[k].g, ns);
                if (!(f > 0.0)) f = 0.0;
                vec3 le = pn_light_radiance_spectral(job->lights, &job->lights->lights[cl->index], cl->emit, sp->b.wl);
                vec3 c = v3_mul(sp->throughput, v3_mul(sp->b.kd, le));
                sp->value = v3_add(sp->value, v3_scale(c, (float)f));
                /* Illuminance on a white receiver: E = pi L F (contour.c, eq. 4-5), in lux for L in
                 * cd/m^2 (docs/units.md). */
                if (lux) sp->lux += (double)PN_PI * (double)pn_photometric(cl->emit) * f;
                /* Its melanopic EDI from the emission at the eye ray's wavelengths (pi L F). */
                if (mel && pn_swl_active(sp->b.wl))
                    sp->mel += (double)PN_PI * (double)pn_swl_melanopic_edi_on(sp->b.wl, le) * f;
                sp->contour_rays += s->ev[k].rays;
                if (cd->trace) {
                    for (int r = 0; r < PN_CPH_COUNT; r++) sp->rays_by[r] += s->ev[k].rays_by[r];
                    sp->visible_rays += s->ev[k].visible_rays;
                    sp->why |= (unsigned)s->ev[k].why;
                }
                if (gradient) {
                    float e = PN_PI * fmaxf(0.0f, v3_luminance(cl->emit));
                    sp->gradient = v3_add(sp->gradient, v3((float)pn_dv3_dot(s->g[k].dg[0], ns) * e,
                                                           (float)pn_dv3_dot(s->g[k].dg[1], ns) * e,
                                                           (float)pn_dv3_dot(s->g[k].dg[2], ns) * e));
                }
            }
        }
    }
}

/* Renders the batch's pixels; the render's ray counts take only pixels with x in
 * [count_x0, count_x1) (a scanline job renders pixels outside the window to complete its spans). */
static pn_status render_pixels(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                               contour_scratch *s, int count_x0, int count_x1) {
    contour_data *cd = job->integrator_data;
    if (!ensure_capacity(s, batch->count)) return PN_ERROR_OUT_OF_MEMORY;
    if (!ensure_span_capacity(s, job, (int)job->contour_span < batch->count ? (int)job->contour_span : batch->count))
        return PN_ERROR_OUT_OF_MEMORY;
    const uint32_t spp = job->spp > 0 ? job->spp : 1;
    const uint32_t S = job->shadow_rays;
    const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) != 0 && job->spectral;
    const bool lux = (job->aovs & PN_AOV_ILLUMINANCE) != 0 || mel;
    span_tally tally = {0, 0, 0, 0, 0};
    uint64_t viewing = 0, contour_rays = 0;
    for (int q = 0; q < batch->count; q++) {
        int px = batch->pixels[q][0], py = batch->pixels[q][1];
        s->scramble[q] = pn_pixel_scramble(job, px, py);
        memset(&s->acc[q], 0, sizeof s->acc[q]);
        memset(&out[q], 0, sizeof out[q]);
        out[q].depth = INFINITY;
    }
    for (uint32_t i = 0; i < spp; i++) {
        if (atomic_load(job->cancel)) break;
        /* Viewing rays for the whole batch first (the paper casts a scanline's). */
        for (int q = 0; q < batch->count; q++) {
            uint32_t scramble = s->scramble[q];
            shade_point *sp = &s->sp[q];
            memset(sp, 0, sizeof *sp);
            /* The driver's eye hit (render/batch.h): in advance under the progressive drivers
             * and under the tiled driver's blocks (contour-mc); through the window's tracers for contour's own rows. */
            pn_eye_hit one;
            const pn_eye_hit *h = pn_batch_eye_hits(job, batch, q, PN_EYE_SEQ_PIXEL, i, 1, &one);
            const pn_eye_path *path = &h->path;
            sp->wl = h->wl; /* zero (off) in RGB mode */
            if (i == 0) {
                out[q].depth = path->first_depth;
                out[q].normal = path->first_normal;
                out[q].albedo = path->first_albedo;
            }
            s->acc[q].specular_rays += path->rays - 1;
            sp->fw = h->weight;
            sp->value = path->emitted;
            if (path->has_point) {
                sp->has_point = true;
                sp->hit = path->hit;
                sp->wo = path->wo;
                sp->throughput = path->throughput;
                sp->b = h->bsdf;
                sp->b.wl = job->spectral ? &sp->wl : NULL;
                sp->diffuse = sp->b.kind == PN_MATERIAL_LAMBERT_BLINN && v3_is_zero(sp->b.ks);
                sp->object = object_key(&path->hit);
                /* Everything the contour integration does not treat: the reference's code. */
                vec3 direct = v3(0, 0, 0), incident = v3(0, 0, 0), incident_wl = v3(0, 0, 0);
                double unused_seconds = 0.0;
                const pn_swl *wl = job->spectral ? &sp->wl : NULL;
                const bool mel_here = mel && pn_swl_active(wl);
                if (pn_reference_direct_irradiance_wl(job, &s->ref, NULL, &sp->b, path->hit.p, path->wo, i, scramble,
                                                      sp->diffuse ? cd->skip : NULL, false, &direct,
                                                      lux ? &incident : NULL, mel_here ? &incident_wl : NULL,
                                                      &s->acc[q].shadow_rays, &unused_seconds)) {
                    sp->value = v3_add(sp->value, v3_mul(path->throughput, v3_scale(direct, 1.0f / (float)S)));
                    /* PN_AOV_ILLUMINANCE: the other lights' part, from the same light samples. */
                    float e = pn_photometric(incident) / (float)S;
                    if (lux && isfinite(e)) sp->lux = (double)e;
                    float m = mel_here ? pn_swl_melanopic_edi_on(wl, incident_wl) / (float)S : 0.0f;
                    if (mel_here && isfinite(m)) sp->mel = (double)m;
                }
            }
        }
        shade_contour_lights(job, cd, batch, s, i, &tally);
        for (int q = 0; q < batch->count; q++) {
            shade_point *sp = &s->sp[q];
            pixel_acc *a = &s->acc[q];
            vec3 value = pn_swl_rgb(&sp->wl, sp->value); /* spectral mode: to sRGB where it is added */
            if (!v3_is_finite(value)) {
                value = v3(0, 0, 0);
                a->non_finite++;
            }
            a->shadow_rays += sp->contour_rays;
            int px = batch->pixels[q][0];
            if (sp->contour_rays > 0 && px >= count_x0 && px < count_x1) {
                viewing++;
                contour_rays += sp->contour_rays;
            }
            if (cd->trace && i == 0 && px >= count_x0 && px < count_x1 && (sp->contour_rays > 0 || sp->culled)) {
                /* x y class why rays-by-phase...: class 0 culled, 1 every ray visible, 2 every ray
                 * hidden, 3 both (penumbra). */
                int cls = sp->contour_rays == 0                  ? 0
                          : sp->visible_rays == sp->contour_rays ? 1
                          : sp->visible_rays == 0                ? 2
                                                                 : 3;
                char line[160];
                int len = snprintf(line, sizeof line, "%d %d %d %u", px, batch->pixels[q][1], cls, sp->why);
                for (int r = 0; r < PN_CPH_COUNT; r++)
                    len += snprintf(line + len, sizeof line - (size_t)len, " %u", sp->rays_by[r]);
                snprintf(line + len, sizeof line - (size_t)len, "\n");
                fputs(line, cd->trace);
            }
            a->n++;
            a->weighted_sum = v3_madd(a->weighted_sum, value, sp->fw);
            a->gradient_sum = v3_madd(a->gradient_sum, sp->gradient, sp->fw);
            if (isfinite(sp->lux)) a->weighted_lux += sp->lux * (double)sp->fw;
            if (isfinite(sp->mel)) a->weighted_mel += sp->mel * (double)sp->fw;
            a->weight_sum += (double)sp->fw;
            double y = (double)v3_luminance(value);
            double delta = y - a->lum_mean;
            a->lum_mean += delta / (double)a->n;
            a->lum_m2 += delta * (y - a->lum_mean);
        }
    }
    for (int q = 0; q < batch->count; q++) {
        const pixel_acc *a = &s->acc[q];
        pn_pixel_estimate *o = &out[q];
        o->eye_rays = a->n;
        o->non_finite = a->non_finite;
        o->shadow_rays = a->shadow_rays;
        o->specular_rays = a->specular_rays;
        if (a->weight_sum != 0.0) {
            o->radiance = v3_scale(a->weighted_sum, (float)(1.0 / a->weight_sum));
            o->gradient = v3_scale(a->gradient_sum, (float)(1.0 / a->weight_sum));
            o->illuminance = (float)(a->weighted_lux / a->weight_sum);
            o->melanopic_edi = (float)(a->weighted_mel / a->weight_sum);
        }
        double var_of_mean = a->n > 1 ? a->lum_m2 / ((double)(a->n - 1) * (double)a->n) : 0.0;
        o->relative_variance = a->lum_mean > 0.0 ? (float)(var_of_mean / (a->lum_mean * a->lum_mean)) : 0.0f;
    }
    atomic_fetch_add(&cd->viewing, viewing);
    atomic_fetch_add(&cd->rays, contour_rays);
    atomic_fetch_add(&cd->integrations, tally.integrations);
    atomic_fetch_add(&cd->interpolated, tally.interpolated);
    atomic_fetch_add(&cd->restarts, tally.restarts);
    atomic_fetch_add(&cd->subdivisions, tally.subdivisions);
    atomic_fetch_add(&cd->culled, tally.culled);
    return PN_OK;
}

/* For drivers that hand out batches (the progressive drivers): spans stay inside the batch. */
static pn_status contour_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                      void *scratch) {
    return render_pixels(job, batch, out, scratch, INT32_MIN, INT32_MAX);
}

/* ---- §5 by scanline: the default driver's whole-image hook ----------------------------------- */

typedef struct scanline_jobs {
    const pn_render_job *job;
    pn_pixel_estimate *pixels; /* the window, width x height */
    int width;
    const pn_batch *window;    /* the driver's tracers of the window's eye samples */
    contour_scratch **scratch; /* per worker */
    int32_t (**row_pixels)[2]; /* per worker: the pixels of one scanline job */
    pn_pixel_estimate **row_out;
    int row_x0, row_count; /* the pixels a scanline job renders (the same for every row) */
    atomic_int failed;
    atomic_long rows_done; /* for the render's progress (rows finish in any order) */
} scanline_jobs;

/* One job per scanline of the window: rows are independent, so the image does not depend on the
 * thread count. The job renders the row from the start of the window's first span segment to
 * the end of its last (segments: contour_span pixels from x = 0 of the full image), so a crop
 * sees the same spans as the full image, and keeps the window's pixels. */
static void scanline_job(void *user, size_t index, int worker) {
    scanline_jobs *sj = user;
    const pn_render_job *job = sj->job;
    if (atomic_load(job->cancel) || atomic_load(&sj->failed)) return;
    if (!sj->scratch[worker]) {
        sj->scratch[worker] = contour_scratch_create(job);
        sj->row_pixels[worker] = malloc((size_t)sj->row_count * sizeof **sj->row_pixels);
        sj->row_out[worker] = malloc((size_t)sj->row_count * sizeof **sj->row_out);
        if (!sj->scratch[worker] || !sj->row_pixels[worker] || !sj->row_out[worker]) {
            atomic_store(&sj->failed, PN_ERROR_OUT_OF_MEMORY);
            return;
        }
    }
    const pn_camera *cam = &job->camera;
    int y = cam->y0 + (int)index;
    int32_t(*px)[2] = sj->row_pixels[worker];
    for (int i = 0; i < sj->row_count; i++) {
        px[i][0] = sj->row_x0 + i;
        px[i][1] = y;
    }
    /* A row is not one 8x8 block: contour draws its numbers per pixel and ignores block_x/y. */
    /* Its eye hits come through the driver's tracers (the window's). */
    pn_batch batch = pn_batch_part(sj->window, sj->row_x0 / 8, y / 8, sj->row_count, (const int32_t(*)[2])px);
    pn_status st = render_pixels(job, &batch, sj->row_out[worker], sj->scratch[worker], cam->x0, cam->x1);
    if (st != PN_OK) {
        atomic_store(&sj->failed, (int)st);
        return;
    }
    memcpy(sj->pixels + (size_t)index * (size_t)sj->width, sj->row_out[worker] + (cam->x0 - sj->row_x0),
           (size_t)sj->width * sizeof *sj->pixels);
    long done = atomic_fetch_add(&sj->rows_done, 1) + 1;
    pn_progress_report(job->progress, (double)done / (double)(cam->y1 - cam->y0));
}

static pn_status contour_render_image(const pn_render_job *job, struct pn_threadpool *pool, const pn_batch *window,
                                      pn_pixel_estimate *pixels, int width, int height) {
    const pn_camera *cam = &job->camera;
    const int S = (int)job->contour_span;
    int workers = pn_threadpool_size(pool);
    scanline_jobs sj;
    memset(&sj, 0, sizeof sj);
    sj.job = job;
    sj.window = window;
    sj.pixels = pixels;
    sj.width = width;
    sj.row_x0 = cam->x0 / S * S;
    long row_x1 = ((long)cam->x1 + S - 1) / S * S;
    if (row_x1 > cam->full_width) row_x1 = cam->full_width;
    if (row_x1 < cam->x1) row_x1 = cam->x1;
    sj.row_count = (int)(row_x1 - sj.row_x0);
    sj.scratch = calloc((size_t)workers, sizeof *sj.scratch);
    sj.row_pixels = calloc((size_t)workers, sizeof *sj.row_pixels);
    sj.row_out = calloc((size_t)workers, sizeof *sj.row_out);
    atomic_init(&sj.failed, 0);
    atomic_init(&sj.rows_done, 0);
    if (sj.scratch && sj.row_pixels && sj.row_out)
        pn_threadpool_run(pool, (size_t)height, scanline_job, &sj);
    else
        atomic_store(&sj.failed, PN_ERROR_OUT_OF_MEMORY);
    for (int w = 0; w < workers; w++) {
        if (sj.scratch) contour_scratch_free(sj.scratch[w]);
        if (sj.row_pixels) free(sj.row_pixels[w]);
        if (sj.row_out) free(sj.row_out[w]);
    }
    free(sj.scratch);
    free(sj.row_pixels);
    free(sj.row_out);
    return (pn_status)atomic_load(&sj.failed);
}

/* contour's scanline hook lets §5 spans run along whole rows; contour-mc works in blocks. */
/* The eye rays every pixel takes: the fixed spp (default 1), which the drivers trace in advance
 * for render_batch. */
static uint32_t contour_batch_hits(const pn_render_job *job) {
    return job->spp > 0 ? job->spp : 1;
}

const pn_integrator pn_integrator_contour = {
    .name = "contour",
    .prepare = contour_prepare,
    .release = contour_release,
    .report = contour_report,
    .finish = contour_finish,
    .scratch_create = contour_scratch_create,
    .scratch_free = contour_scratch_free,
    .render_batch = contour_render_batch,
    .render_image = contour_render_image,
    .batch_hits = contour_batch_hits,
};

const pn_integrator pn_integrator_contour_mc = {
    .name = "contour-mc",
    .prepare = contour_mc_prepare,
    .release = contour_release,
    .report = contour_report,
    .finish = contour_finish,
    .scratch_create = contour_scratch_create,
    .scratch_free = contour_scratch_free,
    .render_batch = contour_render_batch,
    .batch_hits = contour_batch_hits,
};
