/* integrator.h — the integrators' side of the batch interface (render/batch.h): the capability
 * queries answered from the method table and the integrators themselves. Only integrators/ and
 * the registry include this; drivers reach integrators through integrators/registry.h. */
#ifndef PN_INTEGRATORS_INTEGRATOR_H
#define PN_INTEGRATORS_INTEGRATOR_H

#include "render/batch.h"

#include <stdbool.h>
#include <stdint.h>

/* Capabilities from the method table (registry.c): whether the integrator fills
 * pn_pixel_estimate.emitted (PN_CAP_EMITTED), so that the progressive drivers interpolate only the
 * rest; and how many eye rays per pixel it traces as samples 0..n-1 of pn_pixel_eye_sample, each
 * weighted by its filter weight (PN_CAP_EYE_SAMPLES: job->spp; else 0). */
bool pn_integrator_reports_emitted(const pn_integrator *integrator);
uint32_t pn_integrator_pixel_eye_samples(const pn_integrator *integrator, const pn_render_job *job);
/* NULL when the integrator works under the subsampling drivers (dcm, painter, uniform:
 * PN_CAP_PROGRESSIVE), else why it does not, as its method table entry says (issue 18). */
const char *pn_integrator_progressive_refusal(const pn_integrator *integrator);
/* The integrator of the table entry of that kind; NULL if unknown. */
const pn_integrator *pn_integrator_find(pn_integrator_kind kind);

/* The integrators, each defined at the bottom of its own file. */
extern const pn_integrator pn_integrator_reference;
extern const pn_integrator pn_integrator_ias;
/* contour (Vedel 1993) and contour-mc (Kok & Jansen 1992): src/integrators/contour*.c */
extern const pn_integrator pn_integrator_contour;
extern const pn_integrator pn_integrator_contour_mc;

extern const pn_integrator pn_integrator_vpl;
extern const pn_integrator pn_integrator_lightcuts;
extern const pn_integrator pn_integrator_illumcut;

#endif
