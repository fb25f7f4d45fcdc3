/* illumcut.h — what the three VPL integrators share (vpl, lightcuts, illumcut): the VPL set and
 * light tree built in prepare() (preprocessing, timed), the shading points of a pixel's eye
 * samples, and the statistics they accumulate. Declared here, defined in vpl_common.c. */
#ifndef PN_INTEGRATORS_ILLUMCUT_H
#define PN_INTEGRATORS_ILLUMCUT_H

#include "integrators/integrator.h"
#include "lights/light_tree.h"
#include "lights/vpl.h"
#include "shade/bsdf.h"

#include <math.h>
#include <stdatomic.h>

typedef struct pn_vpl_data {
    pn_vpl_set set;
    pn_light_tree tree; /* empty for the vpl integrator */
    double vpl_seconds, tree_seconds;
    /* Totals over the render (lightcuts: added by workers). */
    _Atomic uint64_t bound_evaluations, cut_nodes, points;
    double point_tree_seconds, phase1_seconds, phase2_seconds;
    uint64_t pairs;
} pn_vpl_data;

/* Builds the VPL set (and the light tree when with_tree) into job->integrator_data. */
pn_status pn_vpl_prepare(pn_render_job *job, bool with_tree, pn_err *err);
void pn_vpl_release(pn_render_job *job);
void pn_vpl_report(const pn_render_job *job, pn_render_stats *stats);

/* Eye samples per pixel of the VPL integrators: spp, or 1 when spp is 0 (adaptive). */
static inline uint32_t pn_vpl_spp(const pn_render_job *job) {
    return job->spp > 0 ? job->spp : 1u;
}
/* The same, as pn_integrator.batch_points: vpl and lightcuts take their points from the batch. */
/* The receiver r with its BRDF replaced by a white Lambertian of reflectance pi (f = 1): what it
 * reflects, M G I = cos G I, is the irradiance from each VPL, for PN_AOV_ILLUMINANCE and the
 * calculation grids (vpl_common.c). */
pn_vpl_receiver pn_vpl_irradiance_receiver(const pn_vpl_receiver *r);
uint32_t pn_vpl_batch_points(const pn_render_job *job);

/* pn_shading_point, one eye sample of a pixel followed through specular chains, is render/'s
 * (render/batch.h): the tiled driver traces them for the VPL integrators. */

/* Lightcuts for one receiver outside a render (lightcuts.c; used by the tests): the estimate, the
 * sum of the final cut's error bounds (the guarantee: |estimate - exact| <= that sum), the cut
 * size and the shadow rays. */
typedef struct pn_lightcut_context {
    const pn_lights *lights;
    const pn_accel *accel;
    const pn_vpl_set *set;
    const pn_light_tree *tree;
    float error_bound;
    uint32_t max_cut;
    bool thin_glass; /* shadow rays pass thin glass panes (pn_vpl_transmittance); false: they block */
} pn_lightcut_context;
bool pn_lightcut_eval(const pn_lightcut_context *cx, const pn_vpl_receiver *r, vec3 *radiance, float *bound_sum,
                      uint32_t *cut_size, uint32_t *shadow_rays);

/* Builds an illumcut point tree over the receivers and checks its invariants (illumcut.c): node
 * ranges contiguous, children partitioning their parent, every point in exactly one leaf, boxes,
 * cones and BRDF ranges containing the node's points. Returns the node count, -10 - k when
 * invariant k (1..9, in the order above) is violated, -2 when out of memory. */
int pn_illumcut_check_point_tree(const pn_vpl_receiver *receivers, int count, uint64_t seed);

/* Phase I (illumcut.c): true when a pair failing the criteria refines its light cluster Q, false
 * when it refines its point cluster R (radii of R and Q, whether Q's cone is under 20 degrees,
 * which of the two are leaves; never both leaves). */
bool pn_illumcut_phase1_refines_light(float r_radius, float q_radius, bool q_narrow, bool r_leaf, bool q_leaf);

#endif
