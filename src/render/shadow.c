/* shadow.c — the shadow-ray query of every integrator: opaque occlusion, and thin glass panes
 * passed with their Fresnel slab transmittance (RADIANCE's glass, Cycles' transparent shadows)
 * unless the render asks for pbrt-v4's opaque glass (option opaque-glass). */
#include "render/render_job.h"

float pn_shadow_transmittance(const pn_render_job *job, vec3 o, vec3 d, float tmin, float tmax) {
    if (job->opaque_glass || !pn_accel_has_thin_glass(job->accel))
        return pn_accel_occluded(job->accel, o, d, tmin, tmax) ? 0.0f : 1.0f;
    return pn_accel_transmittance(job->accel, o, d, tmin, tmax);
}
