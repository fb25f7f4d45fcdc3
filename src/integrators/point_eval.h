/* point_eval.h — illuminance at a calculation point with no camera, by the estimators of the
 * integrators that produce the illuminance AOV (integrators/point_eval.c; pn_illuminance). */
#ifndef PN_INTEGRATORS_POINT_EVAL_H
#define PN_INTEGRATORS_POINT_EVAL_H

#include "integrators/integrator.h"

/* Per-worker scratch for pn_point_illuminance (NULL when out of memory); free with
 * pn_point_scratch_free (NULL accepted). */
void *pn_point_scratch_create(const pn_render_job *job, const pn_integrator *integrator);
void pn_point_scratch_free(const pn_integrator *integrator, void *scratch);

/* The illuminance (lux) at point p on the side of unit normal n, point number `index` (which
 * seeds its samples). The integrator must be reference, vpl or lightcuts, prepared
 * (job->integrator_data). With edi not NULL (spectral mode) also the melanopic EDI (lux, CIE
 * S 026) from the same light samples (reference) or VPLs and cuts (vpl, lightcuts) at spp
 * (default 64) sets of wavelengths of the point's own. False when out of memory. */
bool pn_point_illuminance(const pn_render_job *job, const pn_integrator *integrator, void *scratch, vec3 p, vec3 n,
                          uint32_t index, double *lux, double *edi);

/* Whether the integrator can evaluate points (illuminance, and the melanopic EDI in spectral
 * mode). */
bool pn_point_supported(const pn_integrator *integrator);

#endif
