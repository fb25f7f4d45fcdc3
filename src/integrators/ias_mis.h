/* ias_mis.h — multiple importance sampling of ias's light samples with BSDF samples (issue 15,
 * option ias-mis; see ias.c's header and docs/methods/ias.md, "MIS with BSDF sampling").
 *
 * What ias.c needs besides its own PDFs: which light an emitting surface hit belongs to, the
 * solid-angle density with which pn_light_sample_point gives a direction towards a light, and the
 * BSDF ray itself (closest hit, thin glass panes passed as shadow rays pass them). */
#ifndef PN_INTEGRATORS_IAS_MIS_H
#define PN_INTEGRATORS_IAS_MIS_H

#include "render/render_job.h"

/* The codes of ias-mis's choices, in their declared order. */
enum { PN_IAS_MIS_OFF = 0, PN_IAS_MIS_ON = 1, PN_IAS_MIS_GLOSSY = 2 };

/* Emitting surface -> light index, built once per render. */
typedef struct pn_ias_mis_map {
    int *mesh_base;    /* per scene mesh: first slot in tri_light, -1 when it emits nothing */
    int *tri_light;    /* per emitting triangle: its light, or -1 (dropped, zero area) */
    int *sphere_light; /* per scene sphere: its light, or -1 */
} pn_ias_mis_map;

pn_status pn_ias_mis_map_build(const pn_render_job *job, pn_ias_mis_map *map, pn_err *err);
void pn_ias_mis_map_free(pn_ias_mis_map *map);

/* The light an eye or BSDF ray hit, or -1 (not an emitter ias samples: instances, dropped). */
int pn_ias_mis_light_of_hit(const pn_ias_mis_map *map, const pn_hit *hit);

/* The power heuristic's weight of a strategy of density a against one of density b (one sample
 * each): a^2 / (a^2 + b^2); 1 when b is 0. */
static inline double pn_ias_mis_weight(double a, double b) {
    if (!(b > 0.0)) return 1.0;
    if (!(a > 0.0)) return 0.0;
    const double r = b / a;
    return 1.0 / (1.0 + r * r);
}

/* Traces the BSDF ray o + t wi (t > 0) past thin glass panes (unless the render makes them
 * opaque): *hit is the first other surface (true), or the ray left the scene (false). *trans is
 * the panes' transmittance on the way there as a shadow ray to that point (to infinity on a miss)
 * sees it. */
bool pn_ias_mis_trace(const pn_render_job *job, vec3 o, vec3 wi, pn_hit *hit, float *trans);

#endif
