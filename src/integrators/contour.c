/* contour.c — Approximate Contour Integration (Vedel 1993, "Computing Illumination from Area Light
 * Sources by Approximate Contour Integration"): direct light from planar convex area sources
 * (rectangles and triangles of emitting meshes, detected at load by lights/lights.c, and disks as
 * polygons) on diffuse
 * receivers, by integrating eq. 4 over an approximate polygonal contour of the visible part of
 * the source. Every other light, and every light at receivers with a glossy lobe, is estimated
 * by the reference integrator's code (reference_direct.c) in the same render.
 *
 * The parts of the paper, as named in the code:
 *  - §2, eq. 4-5: contour_math.c. Radiance leaving a diffuse receiver of reflectance kd lit by a
 *    source of radiance L (W m^-2 sr^-1) with form factor F (dimensionless):
 *    E = pi L F (W m^-2), and L_o = (kd / pi) E = kd L F.
 *  - §3.1 marching squares: the source is diced into p x p squares (contour_grid - 1 = 2 by
 *    default: the paper's 9 first-level samples); process_square() sorts each square into the
 *    four cases of Fig. 3 (case 4 decided by a ray at the centre); dichotomy() locates the
 *    crossing on each side with `contour_steps` second-level rays; the midpoint of the final
 *    interval is the contour vertex.
 *  - §3.2 corners and validity: one more contour point per piece of contour (diagonal for cases
 *    2 and 3, semi-diagonals for case 4, Fig. 4); the form-factor difference dF of the triangle it
 *    adds is compared with the strip threshold (pn_contour_strip_threshold); if exceeded the
 *    square is split as a quadtree with one dichotomy step fewer. A side whose midpoint, newly
 *    sampled, contradicts two equal endpoints is an inconsistency for the neighbour: the whole
 *    source restarts one level finer (restart in pn_contour_integrate()).
 *  - §3.3 the sample array: one array of (N+1)^2 visibility values per pixel with
 *    N = p 2^steps; every ray (first level, dichotomies on sides and diagonals, centres, side
 *    midpoints) goes to a point of it, so squares, subdivisions and restarts share rays.
 *  - §4 gradients: with PN_AOV_GRADIENT, G and its derivatives (eq. 8-10) are accumulated; the
 *    points of the contour that come from dichotomy are replaced by points on the obstacle
 *    (Fig. 5), at the distance where the hidden sample's ray hit it.
 *  - §5 the image algorithm (contour_render.c): the default driver renders the image by
 *    scanlines (contour_render_image(), one job per row); shade_contour_lights() cuts runs of
 *    adjacent pixels of a row on the same object (at most contour_span long) into spans; shaft
 *    culling (Haines & Wallace 1991) of the scene's objects between the span and the source
 *    (shaft_has_candidates()) — no candidate: the unoccluded closed form, no rays; else
 *    shade_span(): a full contour integration at the first pixel, then only first-level rays at
 *    the next pixels while their pattern stays the same; the pixel where it changed gets a full
 *    integration (it opens the next run), so does the middle of the run, and the pixels in
 *    between get G by quadratic interpolation, projected on their own normal (or linear
 *    interpolation without the middle, see the departures). The first-level
 *    density doubles after an integration that subdivided to depth two or restarted, and halves
 *    again after one that needed no subdivision. Where the rays go: bench/contour/RESULTS.md.
 *
 * Departures from the paper, and why:
 *  - Each square's visible part is integrated as its own closed polygon (the square's visible
 *    corners, the crossings, the extra validity points) instead of collecting one global contour.
 *    The square sides shared by two squares cancel out exactly, so the sum is the paper's contour
 *    integral over the visible pieces of the border and the contour; but each polygon can be
 *    clipped to the receiver's horizon exactly, which the paper does not discuss. Points below
 *    the horizon are classified visible without a ray (the clipping removes them).
 *  - The extra validity point is kept in the contour when the test passes (it is free and
 *    closer to the silhouette).
 *  - The strip threshold is computed from the segment actually tested; its length halves with
 *    the square, which is the paper's "threshold divided by two".
 *  - A contradicted side midpoint (not on the source border) restarts the pass only when a square
 *    already integrated in this pass has it inside one of its sides (the paper's "if the
 *    neighbour had already been treated"); a square not yet treated finds the contradiction
 *    among the samples already traced on its sides (pn_contour_side_contradicted, no rays) and
 *    subdivides, as the paper's forced subdivision. (Before: every contradiction restarted;
 *    bench/contour/RESULTS.md, "Where the rays go".) At most one
 *    restart per integration (PN_CONTOUR_MAX_RESTARTS): after it, inconsistencies are accepted,
 *    which leaves the neighbour's contour as coarse as if the midpoint had not been sampled.
 *  - Dichotomies start from a guess (dichotomy()): the final interval where the nearest pixel
 *    integrated before (at most 8 pixels away on the row, PN_CONTOUR_HINT_DISTANCE in
 *    contour_render.c) saw the contour cross the same array line; two or three rays confirm it,
 *    else the paper's dichotomy runs. The paper shares no ray between pixels and neither does
 *    this (the guess is checked with this pixel's own rays); the vertex keeps the dichotomy's
 *    one-cell precision. (bench/contour/RESULTS.md: 48.7 -> 41.1 rays per viewing ray at span 8.)
 *  - The pattern check of §5 traces, at the pixels after a run's first, only the first-level
 *    samples next to a sample of the other visibility in the run's pattern (all of them when
 *    the pattern is uniform): a contour that moves changes the pattern there first. An occluded
 *    island that appears at a sample far from the contour is seen at the run's next integration
 *    instead. (8-13% fewer rays at the same average difference, bench/contour/RESULTS.md.)
 *    From a run's third pixel on, only part of those samples is checked: half (a checkerboard
 *    that alternates with x) in a run with a contour, half and from the sixth pixel a quarter in
 *    a uniform run; where a part differs, the pixels before it that were checked in part are
 *    checked in full, back to the last that matches, so the run ends where a full check would
 *    end it unless a change came and went between two checks of the same sample. A pixel of a
 *    uniform run so checked gets the closed form of the whole source (visible) or nothing
 *    (hidden), what its integration would give. (Section "Islands, partial checks" of
 *    bench/contour/RESULTS.md: 800x800 cornell-contour, hall-many, bathroom-72.)
 *  - Islands (pn_contour_probe_islands): occluded islands between first-level samples (the
 *    killeroo's legs and ears seen from the floor) are invisible to §3.1's marching and biased
 *    the paper's 3x3 grid bright by +1.7 levels in penumbra. Before each integration, probes
 *    are traced: scouts on a lattice of the whole source (with the adaptive density the 4
 *    centres of the 3 x 3 grid's squares; with a fixed one the 49 inner points of an 8 x 8
 *    lattice, for the 3 x 3 grid the 3 x 3 inner points of each square's 4 x 4 sub-lattice),
 *    and the islands the hint pixel found (a sample inside one of its squares whose
 *    corners all had the other visibility), one or two probes each. A square whose corners
 *    agree and that holds a probe of the other visibility, or whose approximate contour puts a
 *    probe on the wrong side, is subdivided (§3.2's forced subdivision) down to where the probe
 *    is a corner, and the island's contour is integrated like any other. These subdivisions do
 *    not count in the depth that raises the first-level density.
 *  - A run whose unoccluded form factor at its middle pixel is within 0.3% of the linear
 *    interpolation between its ends (pn_contour_run_is_linear, no rays) is interpolated
 *    linearly, without the middle integration of §5's quadratic; the quadratic stays where the
 *    geometry bends it (under a light, where the form factor peaks between the ends).
 *  - Spans also end where the shading normal turns by more than about 25 degrees between two
 *    adjacent pixels (PN_CONTOUR_SPAN_CREASE_COS): the paper's spans cover "the same object",
 *    and across a crease of one mesh (a box's edge) interpolating G from one face onto the other
 *    is wrong where their horizons cut the source differently.
 *  - The first-level density adapts along the whole row rather than per span (§5 does not say
 *    it restarts with each span; restarting made 8-pixel blocks).
 *  - Spans also end at multiples of contour_span in full-image x (segments), so that a crop
 *    window renders exactly the pixels of the full image: a row job renders the window's row
 *    widened to whole segments and keeps the window's pixels (the extra pixels' rays are not
 *    counted in the statistics). Drivers that hand out batches (the progressive ones) get spans
 *    inside their batch rows as before. A run whose first-level samples are all visible (or all
 *    hidden) is integrated at every pixel, which costs no ray beyond the first level.
 *  - (Branch contour-spans checked runs longer than 8 pixels with two more integrations before
 *    the quadratic interpolation; the streaks it removed came mostly from spans that crossed
 *    creases, and with spans ending there the check cost 8-26% of the rays on cornell-contour
 *    for no better average difference, so interpolation is the paper's again.)
 *  - The raised first-level density is at most twice
 *    the initial one per side (25 samples by default): more made every pattern check of a span
 *    cost 81 rays or more.
 *  - Rays to samples on the source's border aim a hair inside it (PN_CONTOUR_BORDER_INSET), so
 *    that they do not graze the geometry the emitter is set in.
 *  - The sample lattice is slightly warped (lattice_warp) so that it cannot align with regularly
 *    spaced geometry in front of the source.
 *  - Triangles are the unit square with one side collapsed (contour_math.h); disks (§6: "as
 *    polygons") are 12-gons of the disk's area, cut into 5 convex quadrilaterals, each diced as
 *    its own source (contour_render.c); spheres and other emitters go to the reference
 *    estimator.
 *  - Gradients: besides the obstacle points of Fig. 5, a crossing on the source's border slides
 *    along the border as M moves (contour_math.c); its velocity uses the silhouette direction
 *    from its neighbour's obstacle point. Polygons that the horizon clips are differentiated
 *    with fixed points. Interpolated pixels get interpolated gradients.
 *  - Glazing (the paper has no glass): thin glass panes (thindielectric, or dielectric marked
 *    thin; lighting-design.md "Glazing") are no occluders of the contour: a sample is hidden only
 *    by an opaque surface, and one seen through panes is marked glazed (with its transmittance,
 *    pn_accel_transmittance). When an integration saw a glazed sample, it integrates again with
 *    the glazed samples counted hidden (the clear pass, on the same sample array: the panes'
 *    edges become contours, their rays shared), and G = G_clear + T (G_visible - G_clear), T the
 *    mean transmittance of the glazed samples weighted by their form-factor integrand
 *    (glazed_sample()). Exact where T is constant over the glazed part; the Fresnel slab varies
 *    by 0.3% between 0 and 30 degrees of incidence. §5's patterns tell glazed from clear samples
 *    (pn_contour_sample_class), so a run ends where a pane's edge moves; a uniform run seen
 *    through glass is integrated at every pixel. With --opaque-glass, the paper's binary
 *    visibility (panes occlude). Measured on a 1 x 1 source behind a half pane (tests/
 *    test_design_aov.c's scene at 32 x 32, 4 spp, against the reference at 256 spp): rel. L1 of
 *    the image 0.18% (0.13% for the same source without the pane), mean within 0.1%, 1% more
 *    rays than with opaque glass; weighting the visible part by T alone, without the clear pass,
 *    gave 0.70% and 4% column errors where the pane's edge crosses the source. */
#include "integrators/contour_internal.h"

#include "core/rng.h"
#include "core/sobol.h"

#include <stdlib.h>
#include <string.h>

/* ---- the sample array and rays ------------------------------------------------------------ */

enum { VIS_UNKNOWN = 0, VIS_VISIBLE = 1, VIS_HIDDEN = 2 };

/* Restarts one level finer per integration, at most; later inconsistencies are accepted (the
 * neighbour keeps its coarser contour on that side). Without a bound, a complex silhouette
 * (the killeroo's toes) restarts level after level down to one cell per square: thousands of
 * rays for one pixel. PN_CONTOUR_NO_RESTARTS makes it 0. */
#define PN_CONTOUR_MAX_RESTARTS 1

/* How far inside the border (in (u, v)) the rays to border samples aim. */
#define PN_CONTOUR_BORDER_INSET 1e-3

static inline size_t sample_index(const pn_contour_eval *c, int i, int j) {
    return (size_t)j * (size_t)(c->N + 1) + (size_t)i;
}

/* The sample lattice is warped by a fixed monotone map of [0, 1] onto itself, separately in u
 * and v (so lines of constant u or v stay straight on the source): a regular lattice at
 * (grid - 1) 2^k divisions falls exactly on regularly spaced geometry in front of a source (the
 * bars of a window modelled in equal parts, in bathroom-72: every first-level ray hit a bar and
 * the window went dark while random samples saw through it). */
#define PN_CONTOUR_LATTICE_WARP 0.0618

static inline double lattice_warp(double t) {
    return t + PN_CONTOUR_LATTICE_WARP * t * (1.0 - t);
}

static inline pn_dvec3 lattice_point(const pn_contour_eval *c, double u, double v) {
    return pn_contour_source_point(c->src, lattice_warp(u), lattice_warp(v));
}

/* Glazing (our departure): sample k is seen through thin glass; its form-factor weight is the
 * integrand cos_M cos_S / r^2 times the area element of the warped lattice at (u, v). */
static void glazed_sample(pn_contour_eval *c, size_t k, pn_dvec3 rel, double u, double v, float transmittance) {
    c->glazed[k] = 1;
    c->glazed_any = true;
    const pn_contour_source *s = c->src;
    double r2 = pn_dv3_dot(rel, rel);
    pn_dvec3 du = pn_dv3_add(s->e1, pn_dv3_scale(s->k, lattice_warp(v)));
    pn_dvec3 dv = pn_dv3_add(s->e2, pn_dv3_scale(s->k, lattice_warp(u)));
    double jac = pn_dv3_length(pn_dv3_cross(du, dv)) * (1.0 + PN_CONTOUR_LATTICE_WARP * (1.0 - 2.0 * u)) *
                 (1.0 + PN_CONTOUR_LATTICE_WARP * (1.0 - 2.0 * v));
    double w = pn_dv3_dot(rel, c->ns) * fabs(pn_dv3_dot(rel, s->normal)) / (r2 * r2) * jac;
    if (!(w > 0.0)) return;
    c->glass_w += w;
    c->glass_wt += w * (double)transmittance;
}

void pn_contour_eval_set_glazing(pn_contour_eval *c, uint8_t *glazed, uint8_t *vis_clear) {
    c->glazed = c->glass ? glazed : NULL;
    c->vis_clear = vis_clear;
}

uint8_t pn_contour_sample_class(pn_contour_eval *c, int i, int j) {
    uint8_t visible = (uint8_t)pn_contour_sample_visible(c, i, j);
    return c->glazed && c->glazed[sample_index(c, i, j)] ? (uint8_t)(visible | 2u) : visible;
}

/* vis_M(S_ij): traced once per pixel, then read from the array. */
bool pn_contour_sample_visible(pn_contour_eval *c, int i, int j) {
    size_t k = sample_index(c, i, j);
    if (c->vis[k]) return c->vis[k] == VIS_VISIBLE;
    /* Rays aim a hair inside the source's border: a ray to the very edge grazes the geometry the
     * emitter is set in (a housing, the ceiling around it) and would hide a strip of the
     * border that the reference, sampling interior points, sees. */
    double inv = 1.0 / (double)c->N, lo = PN_CONTOUR_BORDER_INSET, hi = 1.0 - PN_CONTOUR_BORDER_INSET;
    double su = fmin(hi, fmax(lo, (double)i * inv)), sv = fmin(hi, fmax(lo, (double)j * inv));
    pn_dvec3 p = lattice_point(c, su, sv);
    pn_dvec3 rel = pn_dv3_sub(p, c->m);
    if (pn_dv3_dot(rel, c->ng) <= 0.0 || pn_dv3_dot(rel, c->ns) <= 0.0) {
        c->vis[k] = VIS_VISIBLE; /* below the horizon: clipped away, no ray needed */
        return true;
    }
    vec3 d = v3_sub(pn_dv3_to(p), c->origin);
    float dist = v3_length(d);
    if (!(dist > 0.0f)) {
        c->vis[k] = VIS_VISIBLE;
        return true;
    }
    d = v3_scale(d, 1.0f / dist);
    float tmax = dist * (1.0f - 1e-4f) - c->eps;
    c->rays++;
    c->rays_by[c->restarted ? PN_CPH_RESTART : c->phase]++;
    bool hidden, glazed = false;
    if (c->glazed) {
        /* Glazing: only opaque surfaces hide the sample; one seen through a pane is glazed. */
        float transmittance = pn_accel_transmittance(c->accel, c->origin, d, 0.0f, tmax);
        hidden = !(transmittance > 0.0f);
        glazed = !hidden && transmittance < 1.0f;
        if (c->gradient) {
            pn_hit h; /* the obstacle point of Fig. 5 (the nearest hit: a pane in front counts) */
            c->thit[k] = hidden && pn_accel_intersect(c->accel, c->origin, d, 0.0f, tmax, &h) ? h.t / dist : 1.0f;
        }
        if (glazed) glazed_sample(c, k, rel, su, sv, transmittance);
    } else if (c->gradient) {
        pn_hit h;
        hidden = pn_accel_intersect(c->accel, c->origin, d, 0.0f, tmax, &h);
        c->thit[k] = hidden ? h.t / dist : 1.0f;
    } else {
        hidden = pn_accel_occluded(c->accel, c->origin, d, 0.0f, tmax);
    }
    c->vis[k] = hidden || (glazed && c->clear_pass) ? VIS_HIDDEN : VIS_VISIBLE;
    if (c->clear_pass) c->vis_all[k] = hidden ? VIS_HIDDEN : VIS_VISIBLE;
    c->visible_rays += !hidden;
    return c->vis[k] == VIS_VISIBLE;
}

/* A contour vertex: parameters on the source, and for dichotomy vertices the hidden sample of
 * the final interval (whose ray tells where the obstacle is). */
typedef struct cvert {
    double u, v;
    int hi, hj; /* -1: a corner of the source grid */
    int border; /* a crossing on the source's border: 1 along u (v fixed), 2 along v; else 0 */
} cvert;

static cvert corner_vertex(const pn_contour_eval *c, int i, int j) {
    return (cvert){(double)i / c->N, (double)j / c->N, -1, -1, 0};
}

/* Dichotomy along the array line from sample a to sample b (different visibility, 2^steps
 * cells apart): `steps` second-level rays; the vertex is the midpoint of the final interval.
 * With a hint (the sample array of a nearby pixel integrated before, contour_render.c), the
 * final interval where the hint's traced samples change along the line is tried first: if this
 * pixel's samples at its ends differ the same way (2 rays), or those of the interval next to it
 * on the side they point to (1 more), that is this pixel's final interval, without dichotomy.
 * The vertex then has the dichotomy's precision (one cell); only which crossing is found, when
 * the line crosses the contour several times, may differ. */
static cvert dichotomy(pn_contour_eval *c, int ia, int ja, int ib, int jb, int steps) {
    bool va = pn_contour_sample_visible(c, ia, ja);
    int s = 0;
    if (c->hint && steps >= 2) {
        /* The final interval where the nearby pixel's traced samples change along this line:
         * if this pixel's samples at its ends differ the same way, the crossing is there. */
        int n = 1 << steps, di = (ib - ia) / n, dj = (jb - ja) / n;
        for (int t = 0; t < n; t++) {
            uint8_t h0 = c->hint[sample_index(c, ia + t * di, ja + t * dj)];
            uint8_t h1 = c->hint[sample_index(c, ia + (t + 1) * di, ja + (t + 1) * dj)];
            if (!h0 || !h1 || h0 == h1) continue;
            /* This pixel's own interval: the hint's, or the next one on the side the ends say
             * the crossing moved to (one more ray). */
            bool v0 = pn_contour_sample_visible(c, ia + t * di, ja + t * dj);
            bool v1 = pn_contour_sample_visible(c, ia + (t + 1) * di, ja + (t + 1) * dj);
            int found = -1;
            if (v0 == va && v1 != va)
                found = t;
            else if (v0 != va && t > 0 && pn_contour_sample_visible(c, ia + (t - 1) * di, ja + (t - 1) * dj) == va)
                found = t - 1;
            else if (v0 == va && v1 == va && t + 2 <= n &&
                     pn_contour_sample_visible(c, ia + (t + 2) * di, ja + (t + 2) * dj) != va)
                found = t + 1;
            if (found >= 0) {
                ia += found * di;
                ja += found * dj;
                ib = ia + di;
                jb = ja + dj;
                s = steps;
            }
            break;
        }
    }
    for (; s < steps; s++) {
        int mi = (ia + ib) / 2, mj = (ja + jb) / 2;
        if (pn_contour_sample_visible(c, mi, mj) == va) {
            ia = mi;
            ja = mj;
        } else {
            ib = mi;
            jb = mj;
        }
    }
    cvert x = {0.5 * (double)(ia + ib) / c->N, 0.5 * (double)(ja + jb) / c->N, ib, jb, 0};
    if (!va) {
        x.hi = ia;
        x.hj = ja;
    }
    return x;
}

/* The 3D point used for integration, relative to M: on the source, or (gradients, Fig. 5) on the
 * obstacle along the same direction. */
static pn_dvec3 vertex_point(const pn_contour_eval *c, cvert x) {
    pn_dvec3 rel = pn_dv3_sub(lattice_point(c, x.u, x.v), c->m);
    if (c->gradient && x.hi >= 0) {
        float t = c->thit[sample_index(c, x.hi, x.hj)];
        if (t > 0.0f && t < 1.0f) rel = pn_dv3_scale(rel, (double)t);
    }
    return rel;
}

static void add_polygon(pn_contour_eval *c, const cvert *v, int count) {
    pn_dvec3 p[16];
    if (count > 16) count = 16;
    bool above = true;
    for (int i = 0; i < count; i++) {
        p[i] = vertex_point(c, v[i]);
        above = above && pn_dv3_dot(p[i], c->ns) > 0.0 && pn_dv3_dot(p[i], c->ng) > 0.0;
    }
    if (!c->gradient || !above) {
        pn_contour_add_polygon(&c->acc, p, count, c->ns, c->ng, c->sign, c->gradient);
        return;
    }
    /* Gradients: a crossing on the source's border slides along it as M moves, in the plane
     * through M and the silhouette, whose direction is given by the obstacle point of its
     * neighbour on the contour (pn_contour_border_velocity). */
    pn_dvec3 vel[16][3];
    bool moving[16];
    for (int i = 0; i < count; i++) {
        moving[i] = false;
        if (!v[i].border || v[i].hi < 0) continue;
        int next = (i + 1) % count, prev = (i + count - 1) % count, nb = -1;
        if (v[next].hi >= 0 && !v[next].border)
            nb = next;
        else if (v[prev].hi >= 0 && !v[prev].border)
            nb = prev;
        else if (v[next].hi >= 0)
            nb = next;
        else if (v[prev].hi >= 0)
            nb = prev;
        if (nb < 0) continue;
        pn_dvec3 src_rel = pn_dv3_sub(lattice_point(c, v[i].u, v[i].v), c->m);
        pn_dvec3 ds = pn_dv3_sub(p[nb], p[i]);
        if (!(pn_dv3_length(ds) > 0.0)) continue;
        const pn_contour_source *s = c->src;
        pn_dvec3 t = v[i].border == 1 ? pn_dv3_add(s->e1, pn_dv3_scale(s->k, lattice_warp(v[i].v)))
                                      : pn_dv3_add(s->e2, pn_dv3_scale(s->k, lattice_warp(v[i].u)));
        double tl = pn_dv3_length(t);
        if (!(tl > 0.0)) continue;
        pn_contour_border_velocity(pn_dv3_add(src_rel, c->m), pn_dv3_scale(t, 1.0 / tl), pn_dv3_add(p[i], c->m), ds,
                                   c->m, vel[i]);
        moving[i] = true;
        p[i] = src_rel;
    }
    pn_contour_g part = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    for (int i = 0; i < count; i++) {
        int j = (i + 1) % count;
        pn_contour_add_segment_moving(&part, p[i], p[j], moving[i] ? vel[i] : NULL, moving[j] ? vel[j] : NULL, true);
    }
    c->acc.g = pn_dv3_add(c->acc.g, pn_dv3_scale(part.g, c->sign));
    for (int k = 0; k < 3; k++) c->acc.dg[k] = pn_dv3_add(c->acc.dg[k], pn_dv3_scale(part.dg[k], c->sign));
}

/* |dF| of the triangle a, x, b against the form factor of a strip of width eps along a-b. */
static bool piece_valid(const pn_contour_eval *c, cvert a, cvert x, cvert b) {
    pn_dvec3 pa = pn_dv3_sub(lattice_point(c, a.u, a.v), c->m);
    pn_dvec3 px = pn_dv3_sub(lattice_point(c, x.u, x.v), c->m);
    pn_dvec3 pb = pn_dv3_sub(lattice_point(c, b.u, b.v), c->m);
    pn_contour_g t = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    pn_contour_add_segment(&t, pa, px, false);
    pn_contour_add_segment(&t, px, pb, false);
    pn_contour_add_segment(&t, pb, pa, false);
    double df = fabs(pn_dv3_dot(t.g, c->ns));
    double threshold = pn_contour_strip_threshold(pa, pb, c->eps_length, c->ns, c->src->normal);
    return df <= threshold;
}

/* ---- §3.1-3.2: one square of the marching squares ------------------------------------------ */

void pn_contour_add_leaf(pn_contour_eval *c, int i0, int j0, int s) {
    if (c->leaf_count < PN_CONTOUR_MAX_LEAVES) {
        c->leaves[c->leaf_count][0] = (int16_t)i0;
        c->leaves[c->leaf_count][1] = (int16_t)j0;
        c->leaves[c->leaf_count][2] = (int16_t)s;
    }
    c->leaf_count++;
}

/* §3.2: a new sample (i, j) that contradicts the two ends of a side needs backtracking only if a
 * square already integrated in this pass has (i, j) inside one of its sides (it integrated that
 * side as a straight piece without the crossing). A square not yet treated will find the
 * contradiction on its side itself (side_contradicted()) and subdivide. */
bool pn_contour_treated_square_has_on_side(const pn_contour_eval *c, int i, int j) {
    if (c->leaf_count > PN_CONTOUR_MAX_LEAVES) return true; /* not all remembered */
    for (int l = 0; l < c->leaf_count; l++) {
        int a = c->leaves[l][0], b = c->leaves[l][1], s = c->leaves[l][2];
        bool on_h = (j == b || j == b + s) && i > a && i < a + s;
        bool on_v = (i == a || i == a + s) && j > b && j < b + s;
        if (on_h || on_v) return true;
    }
    return false;
}

/* True when the samples already traced inside the side from (ia, ja) to (ib, jb) (s cells long)
 * change visibility more often than its ends say: the contour crosses it where the square's
 * marching would not see it, which forces the square's subdivision (§3.2). Reads no new rays. */
bool pn_contour_side_contradicted(const pn_contour_eval *c, int ia, int ja, int ib, int jb, int s) {
    int di = (ib - ia) / s, dj = (jb - ja) / s, changes = 0;
    uint8_t last = c->vis[sample_index(c, ia, ja)], end = c->vis[sample_index(c, ib, jb)];
    for (int t = 1; t < s; t++) {
        uint8_t x = c->vis[sample_index(c, ia + t * di, ja + t * dj)];
        if (x == VIS_UNKNOWN) continue;
        changes += x != last;
        last = x;
    }
    changes += end != last;
    return changes > (c->vis[sample_index(c, ia, ja)] != end);
}

/* Whether point (u, v) lies inside the polygon (even-odd rule, in the source's (u, v)). */
static bool inside_polygon(const cvert *p, int n, double u, double v) {
    bool in = false;
    for (int a = 0, b = n - 1; a < n; b = a++)
        if ((p[a].v > v) != (p[b].v > v) && u < (p[b].u - p[a].u) * (v - p[a].v) / (p[b].v - p[a].v) + p[a].u) in = !in;
    return in;
}

/* True when a traced probe strictly inside the square (i0, j0, s) has a visibility other than the
 * visible polygons of the square's approximate contour say. */
static bool probe_misplaced(const pn_contour_eval *c, int i0, int j0, int s, cvert (*poly)[12], const int *counts,
                            int polys) {
    for (int k = 0; k < c->probe_count; k++) {
        int i = c->probe[k][0], j = c->probe[k][1];
        if (i <= i0 || i >= i0 + s || j <= j0 || j >= j0 + s) continue;
        uint8_t x = c->vis[sample_index(c, i, j)];
        if (x == VIS_UNKNOWN) continue;
        bool in = false;
        for (int p = 0; p < polys && !in; p++)
            in = inside_polygon(poly[p], counts[p], (double)i / c->N, (double)j / c->N);
        if (in != (x == VIS_VISIBLE)) return true;
    }
    return false;
}

/* Sides k = 0..3 join corners k and k + 1 (counter-clockwise in (u, v)). */
static void process_square(pn_contour_eval *c, int i0, int j0, int d, int depth) {
    if (c->restart) return;
    const int s = 1 << d;
    const int ci[4] = {i0, i0 + s, i0 + s, i0}, cj[4] = {j0, j0, j0 + s, j0 + s};
    bool v[4];
    int nv = 0;
    c->phase = depth == 0 ? PN_CPH_FIRST : PN_CPH_SUBDIV;
    for (int k = 0; k < 4; k++) {
        v[k] = pn_contour_sample_visible(c, ci[k], cj[k]);
        nv += v[k];
    }
    if (depth > c->max_depth && c->island_nest == 0) c->max_depth = depth;
    cvert corner[4];
    for (int k = 0; k < 4; k++) corner[k] = corner_vertex(c, ci[k], cj[k]);
    const bool test = d >= 1 && !(c->flags & PN_CONTOUR_NO_VALIDITY);
    bool forced = false, island = false;
    if (test)
        for (int k = 0; k < 4 && !forced; k++)
            forced = pn_contour_side_contradicted(c, ci[k], cj[k], ci[(k + 1) & 3], cj[(k + 1) & 3], s);
    if (test && !forced && (nv == 0 || nv == 4) && c->probe_count > 0 &&
        pn_contour_probe_contradicts(c, i0, j0, s, nv == 4 ? VIS_VISIBLE : VIS_HIDDEN)) {
        /* An island probe inside a square whose corners agree: subdivide down to it. */
        forced = island = true;
        c->islands_found++;
    }
    if (forced) {
        c->forced++;
        if (island) c->island_nest++;
        goto subdivide;
    }
    if (nv == 0) { /* case 1, hidden */
        pn_contour_add_leaf(c, i0, j0, s);
        return;
    }
    if (nv == 4) { /* case 1, visible */
        add_polygon(c, corner, 4);
        pn_contour_add_leaf(c, i0, j0, s);
        return;
    }
    /* Cases 2-4: crossings on the sides whose ends differ. */
    cvert x[4];
    c->phase = PN_CPH_SIDE;
    for (int k = 0; k < 4; k++) {
        int k1 = (k + 1) & 3;
        if (v[k] != v[k1]) {
            x[k] = dichotomy(c, ci[k], cj[k], ci[k1], cj[k1], d);
            bool on_border =
                (k == 0 && j0 == 0) || (k == 1 && i0 + s == c->N) || (k == 2 && j0 + s == c->N) || (k == 3 && i0 == 0);
            if (on_border) x[k].border = (k & 1) ? 2 : 1;
        }
    }
    const bool case4 = nv == 2 && v[0] == v[2];
    bool centre_visible = true;
    int mi = i0 + s / 2, mj = j0 + s / 2;
    c->phase = PN_CPH_CENTRE;
    if (case4 && d >= 1) centre_visible = pn_contour_sample_visible(c, mi, mj);
    /* Pieces of contour: each leaves the visible region on side `exit` and comes back on side
     * `entry`; extra[] is its validity point (Fig. 4). */
    int exits[2], entries[2], pieces = 0;
    bool has_extra[2] = {false, false};
    cvert extra[2];
    for (int k = 0; k < 4; k++) {
        int k1 = (k + 1) & 3;
        if (!(v[k] && !v[k1])) continue;
        exits[pieces] = k;
        if (case4 && !centre_visible)
            entries[pieces] = (k + 3) & 3; /* around visible corner k */
        else {
            int e = k1;
            while (!(!v[e] && v[(e + 1) & 3])) e = (e + 1) & 3;
            entries[pieces] = e;
        }
        pieces++;
    }
    if (test) {
        c->phase = PN_CPH_DIAG;
        if (nv == 1 || nv == 3) { /* case 2: diagonal from the odd corner */
            int o = 0;
            for (int k = 0; k < 4; k++)
                if ((nv == 1) == v[k]) o = k;
            int q = (o + 2) & 3;
            extra[0] = dichotomy(c, ci[o], cj[o], ci[q], cj[q], d);
            has_extra[0] = true;
        } else if (!case4) { /* case 3: one of the two diagonals, chosen at random */
            int o = (int)(pn_hash3(c->hash, (uint64_t)i0, (uint64_t)j0 * 65537u + (uint64_t)d) & 1u);
            extra[0] = dichotomy(c, ci[o], cj[o], ci[o + 2], cj[o + 2], d);
            has_extra[0] = true;
        } else { /* case 4: semi-diagonals to the centre */
            for (int p = 0; p < pieces; p++) {
                /* The corner the piece goes around: the hidden one cut off (centre visible) or
                 * the visible one kept (centre hidden). */
                int k = centre_visible ? (exits[p] + 1) & 3 : exits[p];
                extra[p] = dichotomy(c, ci[k], cj[k], mi, mj, d - 1);
                has_extra[p] = true;
            }
        }
        bool valid = true;
        for (int p = 0; p < pieces && valid; p++)
            if (has_extra[p]) valid = piece_valid(c, x[exits[p]], extra[p], x[entries[p]]);
        if (!valid) {
        subdivide:
            /* Quadtree subdivision. Side midpoints between equal corners are new samples; one
             * that disagrees means the neighbour's contour misses a crossing. */
            c->phase = PN_CPH_SUBDIV;
            for (int k = 0; k < 4; k++) {
                int k1 = (k + 1) & 3;
                if (v[k] != v[k1]) continue;
                bool on_border = (k == 0 && j0 == 0) || (k == 1 && i0 + s == c->N) || (k == 2 && j0 + s == c->N) ||
                                 (k == 3 && i0 == 0);
                int hi = (ci[k] + ci[k1]) / 2, hj = (cj[k] + cj[k1]) / 2;
                if (pn_contour_sample_visible(c, hi, hj) != v[k] && !on_border && (int)c->restarts < c->max_restarts &&
                    pn_contour_treated_square_has_on_side(c, hi, hj)) {
                    c->restart = true;
                    if (island) c->island_nest--;
                    return;
                }
            }
            c->subdivisions++;
            int h = s / 2;
            process_square(c, i0, j0, d - 1, depth + 1);
            process_square(c, i0 + h, j0, d - 1, depth + 1);
            process_square(c, i0 + h, j0 + h, d - 1, depth + 1);
            process_square(c, i0, j0 + h, d - 1, depth + 1);
            if (island) c->island_nest--;
            return;
        }
    }
    /* The visible part as polygons, counter-clockwise like the square. */
    cvert poly[2][12];
    int counts[2] = {0, 0}, polys = 0;
    if (case4 && !centre_visible) {
        for (int p = 0; p < pieces; p++) {
            int k = exits[p], n = 0;
            poly[p][n++] = x[entries[p]];
            poly[p][n++] = corner[k];
            poly[p][n++] = x[k];
            if (has_extra[p]) poly[p][n++] = extra[p];
            counts[polys++] = n;
        }
    } else {
        int n = 0;
        for (int k = 0; k < 4; k++) {
            int k1 = (k + 1) & 3;
            if (v[k]) poly[0][n++] = corner[k];
            if (v[k] != v[k1]) {
                poly[0][n++] = x[k];
                if (v[k])
                    for (int p = 0; p < pieces; p++)
                        if (exits[p] == k && has_extra[p]) poly[0][n++] = extra[p];
            }
        }
        counts[polys++] = n;
    }
    /* Our departure: a probe inside the square that the contour puts on the wrong side (an
     * island or a bay of the silhouette the marching did not see) subdivides the square. */
    if (test && c->probe_count > 0 && probe_misplaced(c, i0, j0, s, poly, counts, polys)) {
        island = true;
        c->islands_found++;
        c->forced++;
        c->island_nest++;
        goto subdivide;
    }
    for (int p = 0; p < polys; p++) add_polygon(c, poly[p], counts[p]);
    pn_contour_add_leaf(c, i0, j0, s);
}

/* ---- islands carried along the row (our departure) ------------------------------------------ */

bool pn_contour_probe_contradicts(const pn_contour_eval *c, int i0, int j0, int s, uint8_t corners) {
    for (int k = 0; k < c->probe_count; k++) {
        int i = c->probe[k][0], j = c->probe[k][1];
        if (i <= i0 || i >= i0 + s || j <= j0 || j >= j0 + s) continue;
        uint8_t x = c->vis[sample_index(c, i, j)];
        if (x != VIS_UNKNOWN && x != corners) return true;
    }
    return false;
}

static void add_probe(pn_contour_eval *c, int i, int j) {
    if (c->probe_count >= PN_CONTOUR_MAX_PROBES) return;
    bool traced = c->vis[sample_index(c, i, j)] != VIS_UNKNOWN;
    c->probe[c->probe_count][0] = (int16_t)i;
    c->probe[c->probe_count][1] = (int16_t)j;
    c->probe_count++;
    c->phase = PN_CPH_PROBE;
    pn_contour_sample_visible(c, i, j);
    c->islands_probed += !traced;
}

void pn_contour_probe_islands(pn_contour_eval *c, const uint8_t *hint, int p) {
    c->probe_count = 0;
    if ((c->flags & PN_CONTOUR_NO_VALIDITY) || p <= 0) return;
    const int s = c->N / p;
    if (s < 4) return; /* the probes sit on the square's 4 x 4 sub-lattice */
    const int q = s / 4;
    if (hint && !(c->flags & PN_CONTOUR_NO_ISLANDS))
        for (int b = 0; b < p; b++)
            for (int a = 0; a < p; a++) {
                const int i0 = a * s, j0 = b * s;
                uint8_t corners = VIS_UNKNOWN;
                bool agree = true;
                for (int k = 0; k < 4 && agree; k++) {
                    uint8_t x = hint[sample_index(c, i0 + (k & 1) * s, j0 + (k >> 1) * s)];
                    if (x == VIS_UNKNOWN) continue;
                    if (corners == VIS_UNKNOWN) corners = x;
                    agree = x == corners;
                }
                if (!agree || corners == VIS_UNKNOWN) continue;
                /* The hint's samples of the other visibility inside the square (sides included,
             * corners not): the island. */
                const uint8_t other = corners == VIS_VISIBLE ? VIS_HIDDEN : VIS_VISIBLE;
                double si = 0.0, sj = 0.0;
                int count = 0;
                for (int j = j0; j <= j0 + s; j++)
                    for (int i = i0; i <= i0 + s; i++)
                        if (hint[sample_index(c, i, j)] == other) {
                            si += i;
                            sj += j;
                            count++;
                        }
                if (count == 0) continue;
                const double ci = si / count, cj = sj / count;
                int oi = (int)floor((ci - i0) / q + 0.5), oj = (int)floor((cj - j0) / q + 0.5);
                oi = oi < 1 ? 1 : oi > 3 ? 3 : oi;
                oj = oj < 1 ? 1 : oj > 3 ? 3 : oj;
                add_probe(c, i0 + oi * q, j0 + oj * q);
                if (c->vis[sample_index(c, i0 + oi * q, j0 + oj * q)] == other) continue;
                /* Not there: the hint's island sample nearest the centroid, if strictly inside. */
                int bi = -1, bj = -1;
                double best = INFINITY;
                for (int j = j0 + 1; j < j0 + s; j++)
                    for (int i = i0 + 1; i < i0 + s; i++)
                        if (hint[sample_index(c, i, j)] == other) {
                            double d2 = (i - ci) * (i - ci) + (j - cj) * (j - cj);
                            if (d2 < best) {
                                best = d2;
                                bi = i;
                                bj = j;
                            }
                        }
                if (bi >= 0 && !(bi == i0 + oi * q && bj == j0 + oj * q)) add_probe(c, bi, bj);
            }
    /* Scouts: probes on a lattice of the whole source, the same for any grid: the points
     * (k N / 4, l N / 4) for odd k, l (scout 1: 4 points, the centres of the paper's 3 x 3
     * grid's squares), (k N / 8, l N / 8) for odd k, l (scout 2: 16) or for 0 < k, l < 8
     * (scout 3: 49, the 3 x 3 inner points of each square of the 3 x 3 grid's 4 x 4
     * sub-lattice), leaving out those on a first-level square's side. */
    if (c->scout > 0) {
        const int m = c->scout == 1 ? 4 : 8;
        for (int l = 1; l < m; l++)
            for (int k = 1; k < m; k++) {
                if (c->scout < 3 && (!(k & 1) || !(l & 1))) continue;
                const int i = (k * c->N + m / 2) / m, j = (l * c->N + m / 2) / m;
                if (i % s == 0 || j % s == 0) continue;
                add_probe(c, i, j);
            }
    }
}

/* One pass of the approximate contour integration over the current sample array; returns the
 * first-level squares per side used (after restarts). */
static int integrate_pass(pn_contour_eval *c, int p) {
    for (;;) {
        int d = 0;
        while ((p << d) < c->N) d++;
        c->acc = (pn_contour_g){{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
        c->restart = false;
        c->max_depth = 0;
        c->leaf_count = 0;
        c->island_nest = 0;
        int s = 1 << d;
        for (int b = 0; b < p && !c->restart; b++)
            for (int a = 0; a < p && !c->restart; a++) process_square(c, a * s, b * s, d, 0);
        if (c->restart && d >= 1) {
            /* §3.2: the whole source one level finer, every traced ray kept in the array. */
            c->restarts++;
            c->restarted = true;
            p *= 2;
            continue;
        }
        break;
    }
    return p;
}

void pn_contour_integrate(pn_contour_eval *c, int p) {
    c->restarted = false;
    c->p_used = integrate_pass(c, p);
    if (!c->glazed || !c->vis_clear || !c->glazed_any) return;
    /* Glazing (our departure): the part of the source seen through panes is the visible part
     * less the part seen clear, integrated again with glazed samples hidden (the panes' edges
     * become contours); it is weighted by the panes' mean transmittance over it. */
    const pn_contour_g all = c->acc;
    const int depth = c->max_depth;
    const bool restarted = c->restarted;
    const uint8_t *hint = c->hint;
    const size_t n = (size_t)(c->N + 1) * (size_t)(c->N + 1);
    for (size_t k = 0; k < n; k++) c->vis_clear[k] = c->glazed[k] ? VIS_HIDDEN : c->vis[k];
    c->vis_all = c->vis;
    c->vis = c->vis_clear;
    c->clear_pass = true;
    c->hint = NULL; /* a neighbour's crossings are those of the visible part */
    integrate_pass(c, p);
    c->vis = c->vis_all;
    c->clear_pass = false;
    c->hint = hint;
    const double t = c->glass_w > 0.0 ? c->glass_wt / c->glass_w : 1.0;
    const pn_contour_g clear = c->acc;
    c->acc.g = pn_dv3_add(clear.g, pn_dv3_scale(pn_dv3_sub(all.g, clear.g), t));
    for (int k = 0; k < 3; k++)
        c->acc.dg[k] = pn_dv3_add(clear.dg[k], pn_dv3_scale(pn_dv3_sub(all.dg[k], clear.dg[k]), t));
    c->max_depth = depth;
    c->restarted = restarted;
}

bool pn_contour_eval_setup(pn_contour_eval *c, const pn_render_job *job, const pn_contour_source *src, vec3 p, vec3 ns,
                           vec3 ng, int N, uint8_t *vis, float *thit, bool gradient, uint64_t hash) {
    memset(c, 0, sizeof *c);
    c->src = src;
    c->accel = job->accel;
    c->m = pn_dv3_from(p);
    c->ns = pn_dv3_from(ns);
    c->ng = pn_dv3_from(ng);
    c->sign = pn_contour_source_sign(src, c->m);
    /* Points on the source's own plane (the emitter's back, its surroundings) see nothing of it. */
    double side = fabs(pn_dv3_dot(pn_dv3_sub(c->m, src->p0), src->normal));
    if (!(side > (double)pn_accel_ray_epsilon(job->accel, p))) c->sign = 0.0;
    c->eps = pn_accel_ray_epsilon(job->accel, p);
    c->origin = v3_madd(p, ng, c->eps);
    c->N = N;
    c->vis = vis;
    c->thit = thit;
    c->gradient = gradient;
    c->hash = hash;
    c->flags = job->contour_flags;
    c->eps_length = src->eps_scale / (double)N;
    c->max_restarts = (job->contour_flags & PN_CONTOUR_NO_RESTARTS) ? 0 : PN_CONTOUR_MAX_RESTARTS;
    c->glass = !job->opaque_glass && pn_accel_has_thin_glass(job->accel);
    return c->sign != 0.0;
}
