/* optics.h — Fresnel reflectance of smooth dielectric interfaces, shared by the BSDFs and by the
 * material mapping (which averages it over the hemisphere for coated materials). */
#ifndef PN_CORE_OPTICS_H
#define PN_CORE_OPTICS_H

#include <math.h>
#include <stdbool.h>

/* Fresnel reflectance of unpolarised light at a smooth dielectric interface, for the cosine of
 * the angle of incidence (on the incident side) and eta = eta_transmitted / eta_incident;
 * 1 under total internal reflection. */
/* The reflectances of the parallel (p) and perpendicular (s) polarisations; false under total
 * internal reflection (then both are 1). */
static inline bool pn_fresnel_polarised(float cos_i, float eta, float *r_p, float *r_s) {
    cos_i = fminf(1.0f, fmaxf(0.0f, cos_i));
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    *r_p = *r_s = 1.0f;
    if (sin2_t >= 1.0f) return false;
    float cos_t = sqrtf(1.0f - sin2_t);
    float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    *r_p = r_par * r_par;
    *r_s = r_perp * r_perp;
    return true;
}

static inline float pn_fresnel_dielectric(float cos_i, float eta) {
    float rp, rs;
    if (!pn_fresnel_polarised(cos_i, eta, &rp, &rs)) return 1.0f;
    return 0.5f * (rp + rs);
}

/* The transmittance of a thin non-absorbing slab (a pane of glass) at the cosine cos_i of the
 * angle of incidence. Each face reflects R (per polarisation); summing the light that passes
 * after 0, 2, 4, ... internal reflections gives (1 - R)^2 sum R^(2k) = (1 - R) / (1 + R). The
 * series is summed for the s and p polarisations apart and averaged, as physics has it and as
 * RADIANCE's glass does; pbrt-v4's ThinDielectricBxDF sums it once with the averaged R, which
 * gives 0.06% less at 30 degrees, 0.36% at 45 and 1.5% at 60 (eta 1.52). */
static inline float pn_thin_glass_transmittance(float cos_i, float eta) {
    float rp, rs;
    if (!pn_fresnel_polarised(cos_i, eta, &rp, &rs)) return 0.0f;
    return 0.5f * ((1.0f - rp) / (1.0f + rp) + (1.0f - rs) / (1.0f + rs));
}

#endif
