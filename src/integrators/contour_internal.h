/* contour_internal.h — what the parts of the contour integrator share: the per-pixel form-factor
 * evaluation of Vedel 1993 §3 (contour.c), used by the image algorithm of §5 (contour_render.c). */
#ifndef PN_INTEGRATORS_CONTOUR_INTERNAL_H
#define PN_INTEGRATORS_CONTOUR_INTERNAL_H

#include "integrators/contour_math.h"
#include "integrators/integrator.h"

#include <stdint.h>

/* What a shadow ray was traced for (bench instrumentation: PN_CONTOUR_TRACE, contour_render.c). */
enum {
    PN_CPH_PATTERN = 0, /* §5: first-level rays of a pixel checked against its run's pattern */
    PN_CPH_FIRST,       /* first-level samples read by an integration (not traced by a check) */
    PN_CPH_SIDE,        /* §3.1 dichotomy along a square's side */
    PN_CPH_DIAG,        /* §3.2 validity point on a diagonal or semi-diagonal */
    PN_CPH_CENTRE,      /* §3.1 case 4: the square's centre */
    PN_CPH_SUBDIV,      /* §3.2 quadtree subdivision: side midpoints and sub-square corners */
    PN_CPH_RESTART,     /* any ray traced by a pass restarted one level finer */
    PN_CPH_PROBE,       /* island probes from a nearby pixel's sample array (pn_contour_probe_islands) */
    PN_CPH_COUNT
};

/* Squares of the current pass already integrated without subdivision, remembered so that a
 * contradicted side midpoint restarts the pass only when such a square lies on that side
 * (§3.2: only an already treated neighbour needs backtracking). More: treated as present. */
#define PN_CONTOUR_MAX_LEAVES 128

/* Island probes per integration, at most (pn_contour_probe_islands). */
#define PN_CONTOUR_MAX_PROBES 128

/* One approximate contour integration of one source at one receiving point M. */
typedef struct pn_contour_eval {
    const pn_contour_source *src;
    const pn_accel *accel;
    pn_dvec3 m, ns, ng; /* receiver and its shading / geometric normals */
    vec3 origin;        /* shadow-ray origin (M offset along ng) */
    float eps;
    double sign;  /* pn_contour_source_sign: 0 when M cannot see the emitting side */
    int N;        /* the sample array has (N+1)^2 points: N = p 2^steps (§3.3) */
    uint8_t *vis; /* 0 unknown, 1 visible, 2 hidden */
    float *thit;  /* gradients: hit distance / sample distance of hidden samples */
    bool gradient;
    uint64_t hash;     /* for the random diagonal of case 3 */
    uint32_t flags;    /* PN_CONTOUR_* */
    int max_restarts;  /* restarts one level finer allowed (§3.2) */
    double eps_length; /* strip width: the length of the smallest dichotomy interval */
    /* results */
    pn_contour_g acc;
    uint32_t rays;
    int phase;                      /* PN_CPH_*: where the next rays are counted */
    uint32_t rays_by[PN_CPH_COUNT]; /* rays by phase */
    uint32_t visible_rays;          /* of `rays`, those that reached the source */
    int why;                        /* render: why the pixel was integrated (bits; 0: it was not) */
    const uint8_t *hint;            /* the sample array of a nearby pixel already integrated, or NULL */
    int max_depth;                  /* deepest quadtree subdivision in the last pass */
    bool restart, restarted;
    uint32_t restarts, subdivisions;
    uint32_t forced; /* subdivisions forced by a contradiction already on a side (§3.2) */
    int leaf_count;  /* leaves[]: (i0, j0, size) of the squares treated in this pass */
    int16_t leaves[PN_CONTOUR_MAX_LEAVES][3];
    int p_used; /* first-level squares per side at the end (after restarts) */
    /* Island probes (pn_contour_probe_islands): samples traced before the marching; a square whose
     * corners all have one visibility and that holds a probe of the other is subdivided. */
    int probe_count;
    int16_t probe[PN_CONTOUR_MAX_PROBES][2];
    int scout;       /* scout probes (pn_contour_probe_islands): 0-3 */
    bool partial;    /* render: only half of its first-level samples were checked (uniform run) */
    int island_nest; /* > 0 inside a subdivision forced by a probe (not counted in max_depth) */
    uint32_t islands_probed, islands_found; /* probes traced; probes that contradicted their square */
    /* Glazing (our departure, contour.c): with `glass`, thin panes pass the rays; glazed[k] = 1
     * for samples seen through a pane (caller-owned per pixel, zeroed, (N+1)^2), vis_clear a
     * scratch array of the same size for the pass in which glazed samples count as hidden; the
     * glazed samples' form-factor weights, and the same times their transmittances. */
    bool glass, glazed_any, clear_pass;
    uint8_t *glazed, *vis_clear, *vis_all;
    double glass_w, glass_wt;
} pn_contour_eval;

/* Prepares an evaluation; the caller owns vis (zeroed, (N+1)^2) and thit (same size, only read
 * with gradients). Returns false when M does not see the emitting side. */
bool pn_contour_eval_setup(pn_contour_eval *c, const pn_render_job *job, const pn_contour_source *src, vec3 p, vec3 ns,
                           vec3 ng, int N, uint8_t *vis, float *thit, bool gradient, uint64_t hash);

/* vis_M of sample (i, j) of the array (0 <= i, j <= N), tracing its ray the first time. */
bool pn_contour_sample_visible(pn_contour_eval *c, int i, int j);

/* Glazing: gives c the arrays of its glazed samples (zeroed) and the clear pass's scratch; without
 * them (or with opaque glass) panes are opaque, the paper's binary visibility. */
void pn_contour_eval_set_glazing(pn_contour_eval *c, uint8_t *glazed, uint8_t *vis_clear);

/* The class of sample (i, j) for §5's patterns: 1 visible, 0 hidden, plus 2 when seen through
 * thin glass (so that a run ends where a pane's edge moves across the source). */
uint8_t pn_contour_sample_class(pn_contour_eval *c, int i, int j);

/* §3.2 inconsistencies, exposed for tests. A square integrated without subdivision in the current
 * pass is remembered (pn_contour_add_leaf); pn_contour_treated_square_has_on_side() says whether
 * one of them has sample (i, j) strictly inside a side (a contradiction there needs the pass to
 * restart); pn_contour_side_contradicted() whether the samples already traced inside the side
 * (ia, ja) -> (ib, jb), s cells long, change visibility more often than its ends say (the square
 * must subdivide). Neither traces rays. */
void pn_contour_add_leaf(pn_contour_eval *c, int i0, int j0, int s);
bool pn_contour_treated_square_has_on_side(const pn_contour_eval *c, int i, int j);
bool pn_contour_side_contradicted(const pn_contour_eval *c, int ia, int ja, int ib, int jb, int s);

/* Our departure (islands): before integrating with p x p first-level squares, traces probes:
 *  - islands carried from `hint` (the sample array of a nearby pixel already integrated, or
 *    NULL): samples of one visibility strictly inside a first-level square whose (known) corners
 *    all have the other. For each such square a probe at the point of the square's 4 x 4
 *    sub-lattice nearest the island's centroid, and when that one does not show the island, at
 *    the hint's island sample nearest the centroid;
 * The probes are kept in c->probe. process_square() subdivides a square whose corners agree and
 * that holds a probe of the other visibility (pn_contour_probe_contradicts), or whose approximate
 * contour puts a probe on the wrong side, down to where the probe is a corner, so that the
 * island's contour is integrated. */
void pn_contour_probe_islands(pn_contour_eval *c, const uint8_t *hint, int p);

/* True when one of c's probes lies strictly inside the square (i0, j0, s) with a visibility
 * other than `corners` (1 visible, 2 hidden). Reads no new rays. */
bool pn_contour_probe_contradicts(const pn_contour_eval *c, int i0, int j0, int s, uint8_t corners);

/* The approximate contour integration of §3 with p x p first-level squares (N divisible by p,
 * N / p a power of two); the result is in c->acc (F = acc.g . ns, with the sign applied). */
void pn_contour_integrate(pn_contour_eval *c, int p);

/* §5's pattern check (contour_render.c, our departure): mask[k] = 1 for the samples of a
 * (p + 1) x (p + 1) first-level pattern (row by row) that have a 4-neighbour of the other
 * visibility; the following pixels of a run check only those. */
void pn_contour_pattern_boundary(const uint8_t *pattern, int p, uint8_t *mask);

/* Our departure (contour_render.c): whether the unoccluded form factor at receiver m, a
 * fraction w of the way from a to b along a run, is within tol (relative) of the linear
 * interpolation between a and b; if so the run is interpolated linearly without its middle
 * integration. */
bool pn_contour_run_is_linear(const pn_contour_source *src, const pn_contour_eval *a, const pn_contour_eval *m,
                              const pn_contour_eval *b, double w, double tol);

/* contour-mc (contour_mc.c): adaptive Monte Carlo sampling of the source in the manner of Kok &
 * Jansen 1992, with the same receiver setup, from cells x cells first cells; returns the form factor estimate and adds its rays
 * to c->rays. */
double pn_contour_mc_form_factor(pn_contour_eval *c, int cells, double threshold, uint32_t max_rays);

#endif
