/* ias_ratio.h — the ratio estimator of Heitz, Hill and McGuire 2018 ("Combining analytic direct
 * illumination and stochastic shadows") inside the default `ias` variant (issue 15; option
 * ias-ratio, reasons and measured effects in ias.c's header and docs/methods/ias.md).
 *
 * Where the unshadowed contribution of a cut entry (a light, or a small cluster of lights) is
 * known in closed form at a region's point, the pass estimate takes it from there and estimates
 * only how much of it the shadow rays find visible, from the same samples:
 *
 *   L = sum_s w_s (v_s - beta_e(s) u_s) + sum_k W_k sum_{e in A_k} beta_e U_k,e
 *
 * with v_s the sample as ias takes it (shadowed, over its probability), u_s the same sample
 * unshadowed with the BSDF's diffuse part (kd / pi) for its entry e(s) in A (0 outside A), w_s =
 * W_k / n_k (region weight over its samples), U_k,e = E[u | k, e] the closed form, and beta the
 * visible fraction used:
 *
 *  - ratio (per pixel): beta = sum_A w v / sum_A w u, one ratio over the pixel's samples in A
 *    (Heitz et al.'s estimator pooled over the pixel's lights: consistent, biased O(1/n));
 *  - cluster: beta_e = the same ratio over the samples of entry e's cluster (the pixel's regions
 *    pooled by cluster id); entries without a sample take the pixel's ratio;
 *  - control: beta_e fixed before the pass (the block's visible fraction of the light so far,
 *    (visible + 0.5) / (count + 1)): a control variate, unbiased for any beta.
 *
 * The glossy lobe stays in v only: u uses the diffuse part, whose integral is the closed form, so
 * the estimate stays consistent (the ratio converges to integral(f V) / integral(f_d)) and only
 * its variance depends on how glossy the surface is. Environment regions, disks, spheres across
 * the horizon and clusters over the member limit are outside A: the plain estimate. */
#ifndef PN_INTEGRATORS_IAS_RATIO_H
#define PN_INTEGRATORS_IAS_RATIO_H

#include "lights/cluster_tree.h"
#include "lights/lights.h"

#include <stdbool.h>
#include <stdint.h>

/* The modes of option ias-ratio, in its declared order (render_job.h keeps the codes). */
enum { PN_IAS_RATIO_OFF = 0, PN_IAS_RATIO_PIXEL = 1, PN_IAS_RATIO_CLUSTER = 2, PN_IAS_RATIO_CONTROL = 3 };

/* The exact unoccluded irradiance (RGB) at p with unit normal n of light l, when it has a closed
 * form there: point, spot, distant, triangle and rectangle lights (Lambert's polygon formula
 * clipped to the horizon), spheres wholly above the horizon (pi L sin^2 a cos t). False for
 * others (disks, spheres across the horizon or around p, environment, goniometric, projection)
 * and for emissions whose luminance is not positive. */
bool pn_ias_light_unshadowed(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n, vec3 *e);

/* The exact unoccluded irradiance of cluster node `node` of forest f: the sum over its lights,
 * false when it has more than max_members lights or one of them has no closed form at p. */
bool pn_ias_cluster_unshadowed(const pn_cluster_forest *f, const pn_lights *lights, int node, int max_members, vec3 p,
                               vec3 n, vec3 *e);

/* One shadow-ray sample of a pixel pass: its region (index among the pixel's regions), its cut
 * entry (an index into the cut arrays; -1 when the entry has no closed form), and v and u as
 * above, already divided by the sample's probability. */
typedef struct pn_ias_ratio_sample {
    int region, entry;
    vec3 v, u;
} pn_ias_ratio_sample;

/* What the pass estimate needs of a region: its weight W_k, its cut entries (cut_first ..
 * cut_first + cut_count in the cut arrays) and its material factor m (the mean over its points of
 * share x throughput x kd / pi), so that U_k,e = m * unshadowed[e]. */
typedef struct pn_ias_ratio_region {
    double weight;
    int cut_first, cut_count;
    vec3 m;
} pn_ias_ratio_region;

/* Scratch for pn_ias_ratio_pass's cluster mode, indexed by cluster id (id_count entries). */
typedef struct pn_ias_ratio_scratch {
    double *num, *den;
    unsigned *count;
    uint32_t *stamp;
    uint32_t now;
    int id_count;
    unsigned *n_of;        /* per region: its samples */
    double *zs, *zv, *zv2; /* per region: residual sums (estimate; variance's, and squared) */
    vec3 *zc;              /* per region: residual RGB sum */
} pn_ias_ratio_scratch;

bool pn_ias_ratio_scratch_init(pn_ias_ratio_scratch *s, int id_count, int max_regions);
void pn_ias_ratio_scratch_free(pn_ias_ratio_scratch *s);

/* The pass estimate of one pixel (see above) from its samples: luminance *lum, colour *rgb, the
 * variance of the estimate *s2 (a stratified estimate over regions, sum W_k^2 s_k^2 / n_k, of the
 * residuals v - beta u: exact for control, the delta method's for the ratios, whose residuals of
 * an entry with a single sample are taken against the pixel's ratio) and the samples *n.
 * unshadowed[e] (RGB, x < 0: not in A) and cut_ids[e] (cluster id) are per cut entry, beta[e]
 * (control mode only) too. */
void pn_ias_ratio_pass(int mode, const pn_ias_ratio_sample *smp, int count, const pn_ias_ratio_region *regions,
                       int region_count, const int *cut_ids, const vec3 *unshadowed, const double *beta,
                       pn_ias_ratio_scratch *sc, double *lum, vec3 *rgb, double *s2, unsigned *n);

#endif
