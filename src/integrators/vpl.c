/* vpl.c — the all-VPL reference (IlluminationCut §4: "the image rendered with all VPLs as our
 * reference image"): every shading point against every VPL of the set, with a shadow ray for each
 * VPL that can light it (eq. 1 summed over S). Threaded by the driver's 8x8 blocks. */
#include "integrators/illumcut.h"

#include "core/photometry.h"
#include "spectral/melanopic.h"

#include <string.h>

static pn_status vpl_prepare(pn_render_job *job, pn_err *err) {
    return pn_vpl_prepare(job, false, err);
}

static pn_status vpl_render_batch(const pn_render_job *job, const pn_batch *batch, pn_pixel_estimate *out,
                                  void *scratch) {
    (void)scratch;
    const pn_vpl_data *d = job->integrator_data;
    const uint32_t spp = pn_vpl_spp(job);
    const bool mel = (job->aovs & PN_AOV_MELANOPIC_EDI) != 0 && job->spectral;
    const bool lux = (job->aovs & PN_AOV_ILLUMINANCE) != 0 || mel;
    for (int pi = 0; pi < batch->count; pi++) {
        if (atomic_load(job->cancel)) return PN_OK;
        pn_pixel_estimate *o = &out[pi];
        memset(o, 0, sizeof *o);
        o->depth = INFINITY;
        vec3 sum = v3(0, 0, 0);
        double wsum = 0.0, lux_sum = 0.0, mel_sum = 0.0;
        for (uint32_t s = 0; s < spp; s++) {
            pn_shading_point sp;
            pn_batch_eye_point(job, batch, pi, s, &sp, o);
            vec3 value = sp.emitted;
            if (sp.has_point) {
                vec3 L = v3(0, 0, 0), E = v3(0, 0, 0), E_wl = v3(0, 0, 0);
                const pn_vpl_receiver white = pn_vpl_irradiance_receiver(&sp.r);
                /* PN_AOV_MELANOPIC_EDI: the white receiver at the eye sample's wavelengths. */
                pn_vpl_receiver white_wl = white;
                white_wl.wl = sp.r.wl;
                const bool mel_here = mel && sp.r.wl.on;
                for (uint32_t k = 0; k < d->set.count; k++) {
                    vec3 wi;
                    float dist;
                    vec3 c = pn_vpl_contribution(job->lights, &d->set.vpls[k], &sp.r, d->set.min_dist2, &wi, &dist);
                    /* PN_AOV_ILLUMINANCE: the same VPL and shadow ray with a white receiver. */
                    vec3 e =
                        lux ? pn_vpl_contribution(job->lights, &d->set.vpls[k], &white, d->set.min_dist2, &wi, &dist)
                            : v3(0, 0, 0);
                    if (v3_is_zero(c) && v3_is_zero(e)) continue;
                    o->shadow_rays++;
                    float t = pn_vpl_transmittance(job->accel, &sp.r, wi, dist, !job->opaque_glass);
                    if (t > 0.0f) L = v3_add(L, t == 1.0f ? c : v3_scale(c, t));
                    if (t > 0.0f) E = v3_madd(E, e, t);
                    if (t > 0.0f && mel_here)
                        E_wl = v3_madd(
                            E_wl,
                            pn_vpl_contribution(job->lights, &d->set.vpls[k], &white_wl, d->set.min_dist2, &wi, &dist),
                            t);
                }
                value = v3_add(value, v3_mul(sp.throughput, L));
                float lx = pn_photometric(E);
                if (lux && isfinite(lx)) lux_sum += (double)lx * (double)sp.weight;
                float m = mel_here ? pn_swl_melanopic_edi_on(&sp.r.wl, E_wl) : 0.0f;
                if (mel_here && isfinite(m)) mel_sum += (double)m * (double)sp.weight;
            }
            value = pn_swl_rgb(&sp.r.wl, value); /* spectral mode: the sample's wavelengths to sRGB */
            if (!v3_is_finite(value)) {
                value = v3(0, 0, 0);
                o->non_finite++;
            }
            sum = v3_madd(sum, value, sp.weight);
            wsum += (double)sp.weight;
        }
        if (wsum != 0.0) o->radiance = v3_scale(sum, (float)(1.0 / wsum));
        if (wsum != 0.0) o->illuminance = (float)(lux_sum / wsum);
        if (wsum != 0.0) o->melanopic_edi = (float)(mel_sum / wsum);
    }
    return PN_OK;
}

const pn_integrator pn_integrator_vpl = {
    .name = "vpl",
    .prepare = vpl_prepare,
    .release = pn_vpl_release,
    .report = pn_vpl_report,
    .render_batch = vpl_render_batch,
    .batch_points = pn_vpl_batch_points,
};
