/* contour_mc.c — the comparison method of Vedel 1993 §5: adaptive Monte Carlo sampling of an area
 * source in the manner of Kok & Jansen 1992 ("Adaptive sampling of area light sources in ray
 * tracing including diffuse interreflection"), without their shadow-pattern coherence, as the
 * paper did. It runs after the same shaft culling as `contour` (contour_render.c), so both cast
 * rays at the same pixels.
 *
 * The source is a quadtree of cells on (u, v), starting from (grid - 1)^2 cells (--contour-grid). Each cell is sampled with four jittered shadow
 * rays, one per quarter (stratified); its estimate is F_cell * (visible fraction), with F_cell the
 * cell's unoccluded form factor (eq. 4 on the cell's outline, exact). A cell whose samples
 * disagree is refined into its four quarters while the standard error of its estimate,
 * F_cell sqrt(q (1 - q) / 4), exceeds `threshold` times the whole source's unoccluded form factor;
 * each quarter keeps the parent's sample that fell in it and gets three new ones. The threshold
 * (--mc-threshold) trades rays for quality: the paper tunes it once to match contour's rays and
 * once to match its quality. Our reading of Kok & Jansen: their test compares the variance of a
 * region's samples with a threshold and subdivides the region; the details of their statistics
 * differ.
 *
 * Glazing (neither paper has glass): a sample seen through thin glass panes counts with their
 * transmittance (the cell's estimate is F_cell times the mean transmittance of its samples, 0 for
 * the hidden ones); refinement still looks at visible against hidden. --opaque-glass: binary. */
#include "integrators/contour_internal.h"

#include "core/rng.h"

#include <string.h>

typedef struct mc_sample {
    double u, v;
    bool visible;
    bool above;          /* above the receiver's horizon (else it carries no light and is not counted) */
    float transmittance; /* glazing: of the thin glass panes crossed (1 without; 0 when hidden) */
} mc_sample;

typedef struct mc_cell {
    double u0, v0, size;
    int depth;
    uint64_t id;
    mc_sample s[4]; /* one per quarter: 0 (low u, low v), 1 (high u), 2 (high v), 3 (both) */
} mc_cell;

static bool trace_visible(pn_contour_eval *c, double u, double v, bool *above, float *transmittance) {
    *transmittance = 0.0f;
    pn_dvec3 p = pn_contour_source_point(c->src, u, v);
    pn_dvec3 rel = pn_dv3_sub(p, c->m);
    *above = !(pn_dv3_dot(rel, c->ng) <= 0.0 || pn_dv3_dot(rel, c->ns) <= 0.0);
    if (!*above) return false;
    vec3 d = v3_sub(pn_dv3_to(p), c->origin);
    float dist = v3_length(d);
    *transmittance = 1.0f;
    if (!(dist > 0.0f)) return true;
    d = v3_scale(d, 1.0f / dist);
    c->rays++;
    float tmax = dist * (1.0f - 1e-4f) - c->eps;
    if (c->glass) {
        /* Glazing: thin panes pass the ray with their transmittance; only opaque surfaces hide. */
        *transmittance = pn_accel_transmittance(c->accel, c->origin, d, 0.0f, tmax);
        return *transmittance > 0.0f;
    }
    if (pn_accel_occluded(c->accel, c->origin, d, 0.0f, tmax)) *transmittance = 0.0f;
    return *transmittance > 0.0f;
}

static double cell_form_factor(const pn_contour_eval *c, const mc_cell *cell) {
    static const double corner[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    pn_dvec3 v[4];
    for (int k = 0; k < 4; k++)
        v[k] = pn_dv3_sub(
            pn_contour_source_point(c->src, cell->u0 + corner[k][0] * cell->size, cell->v0 + corner[k][1] * cell->size),
            c->m);
    pn_contour_g g = {{0, 0, 0}, {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}}};
    pn_contour_add_polygon(&g, v, 4, c->ns, c->ng, c->sign, false);
    return fmax(0.0, pn_dv3_dot(g.g, c->ns));
}

/* A new jittered sample in quarter k of the cell. */
static mc_sample new_sample(pn_contour_eval *c, const mc_cell *cell, int k) {
    uint64_t h = pn_hash3(c->hash, cell->id, (uint64_t)k);
    double h2 = cell->size * 0.5;
    mc_sample s;
    s.u = cell->u0 + ((k & 1) + (double)pn_hash_unit(h)) * h2;
    s.v = cell->v0 + (((k >> 1) & 1) + (double)pn_hash_unit(pn_hash64(h))) * h2;
    s.visible = trace_visible(c, s.u, s.v, &s.above, &s.transmittance);
    return s;
}

double pn_contour_mc_form_factor(pn_contour_eval *c, int cells, double threshold, uint32_t max_rays) {
    pn_contour_g whole;
    pn_contour_source_unoccluded(c->src, c->m, c->ns, c->ng, false, &whole);
    double f_source = pn_dv3_dot(whole.g, c->ns);
    if (!(f_source > 0.0)) return 0.0;
    enum { STACK = 512 };
    mc_cell stack[STACK];
    int top = 0;
    /* cells x cells first cells of four samples each (2 x 2 by default: 16 rays before any
     * refinement). */
    if (cells < 1) cells = 1;
    if (cells * cells > STACK / 2) cells = 8;
    for (int k = 0; k < cells * cells; k++) {
        double size = 1.0 / cells;
        mc_cell cell = {size * (k % cells), size * (k / cells),          size, 1,
                        4096 + (uint64_t)k, {{0, 0, false, false, 0.0f}}};
        for (int j = 0; j < 4; j++) cell.s[j] = new_sample(c, &cell, j);
        stack[top++] = cell;
    }
    double estimate = 0.0;
    while (top > 0) {
        mc_cell cell = stack[--top];
        /* The visible fraction of the cell's part above the horizon (the part F_cell covers). */
        int visible = 0, above = 0;
        double passed = 0.0; /* the visible samples' transmittances (their count without glass) */
        for (int k = 0; k < 4; k++) {
            visible += cell.s[k].visible;
            above += cell.s[k].above;
            if (cell.s[k].visible && cell.s[k].above) passed += (double)cell.s[k].transmittance;
        }
        double f_cell = cell_form_factor(c, &cell);
        double q = above > 0 ? (double)visible / above : 0.0;
        double std_error = above > 0 ? f_cell * sqrt(q * (1.0 - q) / above) : 0.0;
        bool refine = visible > 0 && visible < above && std_error > threshold * f_source && c->rays + 12 <= max_rays &&
                      cell.depth < 12 && top + 4 <= STACK;
        if (!refine) {
            estimate += f_cell * (above > 0 ? passed / above : 0.0);
            continue;
        }
        double h = cell.size * 0.5;
        for (int k = 0; k < 4; k++) {
            mc_cell child = {cell.u0 + (k & 1) * h, cell.v0 + ((k >> 1) & 1) * h, h,
                             cell.depth + 1,        cell.id * 4 + (uint64_t)k,    {{0, 0, false, false, 0.0f}}};
            /* The parent's sample in this quarter stays, in the child's quarter it falls in. */
            mc_sample kept = cell.s[k];
            int kk = (kept.u >= child.u0 + h * 0.5 ? 1 : 0) + (kept.v >= child.v0 + h * 0.5 ? 2 : 0);
            for (int j = 0; j < 4; j++) child.s[j] = j == kk ? kept : new_sample(c, &child, j);
            stack[top++] = child;
        }
    }
    return estimate;
}
