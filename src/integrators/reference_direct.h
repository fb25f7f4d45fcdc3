/* reference_direct.h — the reference integrator's direct-light estimator at one shading point
 * (IAS paper §5.1: a fixed PDF over lights proportional to their unoccluded irradiance, S shadow
 * rays), shared by `reference` and by integrators that hand it the lights they do not treat
 * themselves (`contour`). */
#ifndef PN_INTEGRATORS_REFERENCE_DIRECT_H
#define PN_INTEGRATORS_REFERENCE_DIRECT_H

#include "lights/light_bvh.h"
#include "render/render_job.h"
#include "shade/bsdf.h"

typedef struct pn_reference_direct_scratch {
    float *cdf;    /* light_count + 1 */
    int *index;    /* lights with non-zero weight */
    float *weight; /* unoccluded irradiance of every light */
    int *exact;    /* scratch of pn_lights_irradiance_all */
} pn_reference_direct_scratch;

/* Allocates / frees the arrays for job->lights->count lights; false when out of memory. */
bool pn_reference_direct_init(pn_reference_direct_scratch *s, const pn_render_job *job);
void pn_reference_direct_free(pn_reference_direct_scratch *s);

/* The sum over j < S of the shadow-ray estimates at point p (BSDF b, outgoing wo), drawing
 * dimensions 5-7 of sample index i * S + j of the pixel's scrambled Sobol sequence. Lights are
 * chosen from the PDF over all lights, or, when bvh is not NULL, by descending pbrt-v4's light
 * BVH (--light-sampler bvh). Lights with skip[l] != 0 are left out of the PDF, or contribute
 * nothing when drawn from the BVH (skip may be NULL). Returns false (and adds nothing) when
 * no light has non-zero probability; *sum is then untouched. Adds the shadow rays cast to
 * *shadow_rays and, when timed, the time spent in Embree to *embree_seconds. */
bool pn_reference_direct(const pn_render_job *job, pn_reference_direct_scratch *s, const pn_light_bvh *bvh,
                         const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i, uint32_t scramble, const unsigned char *skip,
                         bool timed, vec3 *sum, uint32_t *shadow_rays, double *embree_seconds);

/* pn_reference_direct that also estimates, from the same light samples, the irradiance at the
 * point on the side of b->ns (sum over the S samples of L cos / pdf, without the BSDF; RGB
 * W/m^2) into *irradiance. Samples the BSDF turns to zero above the horizon (a black surface)
 * still cast their shadow ray for it. With irradiance NULL it is pn_reference_direct. */
bool pn_reference_direct_irradiance(const pn_render_job *job, pn_reference_direct_scratch *s, const pn_light_bvh *bvh,
                                    const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i, uint32_t scramble,
                                    const unsigned char *skip, bool timed, vec3 *sum, vec3 *irradiance,
                                    uint32_t *shadow_rays, double *embree_seconds);

/* pn_reference_direct_irradiance that also sums, beside the RGB irradiance, the irradiance at
 * b->wl's wavelengths in spectral mode (each sample's radiance at them, L(lambda) cos / pdf) into
 * *irradiance_wl, the input of the melanopic EDI (spectral/melanopic.h). irradiance_wl may be
 * NULL; it is used only with irradiance, and in RGB mode equals *irradiance. */
bool pn_reference_direct_irradiance_wl(const pn_render_job *job, pn_reference_direct_scratch *s,
                                       const pn_light_bvh *bvh, const pn_bsdf *b, vec3 p, vec3 wo, uint32_t i,
                                       uint32_t scramble, const unsigned char *skip, bool timed, vec3 *sum,
                                       vec3 *irradiance, vec3 *irradiance_wl, uint32_t *shadow_rays,
                                       double *embree_seconds);

#endif
