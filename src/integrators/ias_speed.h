/* ias_speed.h — two departures of the default `ias` variant from Donikian et al. 2006 (issue 15),
 * chosen from a diagnosis of bathroom-72-matte (docs/methods/ias.md, "Departures"):
 *
 *  - the irradiance prior: c_U's PDF over a point's cut of the cluster trees follows each
 *    cluster's unoccluded irradiance (as the reference's PDF does per light) instead of being
 *    uniform, with a defensive uniform share so that no cluster of the cut gets probability 0;
 *  - emitter rays: a pixel next to an emitter edge takes more eye rays for what its eye rays see
 *    directly (no shadow rays), decided from its neighbours' eye rays only, so that the decision
 *    does not depend on the pixel's own values (no stopping bias). */
#ifndef PN_INTEGRATORS_IAS_SPEED_H
#define PN_INTEGRATORS_IAS_SPEED_H

#include "lights/cluster_tree.h"
#include "render/batch.h"

#include <stdbool.h>
#include <stdint.h>

/* The uniform share kept in c_U's PDF under the irradiance prior. */
#define PN_IAS_PRIOR_UNIFORM_SHARE 0.05

/* The unoccluded irradiance at p (unit normal n) of cluster node `node` of forest f, times pi (the
 * unit of the environment regions' and the light BVH's priors in ias.c): a leaf's light exactly as
 * the reference PDF computes it (pn_light_irradiance_estimate), an interior node from its power,
 * bounding sphere and the receiver's cosine (an estimate, not a bound). Never negative. */
double pn_ias_cluster_irradiance(const pn_cluster_forest *f, const pn_lights *lights, int node, vec3 p, vec3 n);

/* c_U's PDF under the irradiance prior: out[i] = (1 - s) prior[i] / sum + s / count with s
 * PN_IAS_PRIOR_UNIFORM_SHARE (uniform when the priors sum to 0). Sums to 1. */
void pn_ias_prior_pdf(const double *prior, int count, double *out);

/* The emitter-ray rule for pixel `self` of a batch of `count` pixels at coordinates xy[k][0..1],
 * each of which traced `rays` eye rays: true when the pixel's neighbours (the batch's pixels at
 * most one pixel away, itself excluded) have, together, at least one eye ray that saw emission
 * (hits[k] > 0) and one that did not (hits[k] < rays). */
bool pn_ias_emitter_edge(const int32_t (*xy)[2], const uint32_t *hits, uint32_t rays, int count, int self);

/* `count` eye rays of batch pixel pi for the emitted term only, read from the batch: samples 0..
 * of sequence PN_EYE_SEQ_IAS_EMITTER (render/batch.h; the reference's per-pixel convention under
 * a scramble of their own, independent of ias's block sequence). Adds their filter-weighted
 * emission to *emitted and their filter weights to *weight_sum; returns the number of intersect
 * calls. */
uint32_t pn_ias_emitter_rays(const pn_render_job *job, const pn_batch *batch, int pi, uint32_t count, vec3 *emitted,
                             double *weight_sum);

/* The trees cut's statistics (ias.c, sparse_stats): dense arrays over the cluster ids below
 * PN_IAS_DENSE_IDS ids, hash tables from there on; the images are the same. Tests set another
 * limit (ids <= 0: back to the default) to compare the two. */
#define PN_IAS_DENSE_IDS 65536
void pn_ias_set_dense_limit(int ids);

/* For the tests: a process-wide count of the trees cut's statistics entries aggregated, set from
 * the block's or a pixel's samples, or cleared, in every ias render so far. Per shadow ray it
 * grows as the cluster ids do with dense arrays, as the depth below the cut with hash tables. */
uint64_t pn_ias_stats_work(void);

#endif
