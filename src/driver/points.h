/* points.h — the driver of calculation points (pn_illuminance, driver/points.c), and the job
 * resolution it shares with pn_render (driver/render.c). */
#ifndef PN_DRIVER_POINTS_H
#define PN_DRIVER_POINTS_H

#include "integrators/registry.h"

/* Resolves the settings (zero = default) and the options of the chosen methods into *job. */
pn_status pn_driver_resolve_settings(pn_context ctx, struct pn_scene_s *scene, const pn_render_settings *s,
                                     const pn_method_entry *integ, const pn_method_entry *driver, pn_render_job *job);

/* The common start of pn_render and pn_illuminance: resolves the settings into *job, sets up the
 * progress path in *progress (job->progress points to it) and runs the integrator's prepare().
 * On failure nothing needs releasing (the cancel request is cleared, the context holds the
 * message); on success the caller releases the integrator and destroys *progress. */
pn_status pn_driver_prepare_job(pn_context ctx, struct pn_scene_s *scene, const pn_render_settings *settings,
                                const pn_method_entry *integ, const pn_method_entry *driver, pn_render_job *job,
                                struct pn_progress *progress);

#endif
