/* melanopic.c — s_mel(λ) and the melanopic EDI estimate at an eye sample's wavelengths
 * (melanopic.h). */
#include "spectral/melanopic.h"

#include "spectral/cie.h"
#include "spectral/transport.h"

double pn_cie_smel(double lambda) {
    if (!(lambda >= PN_SMEL_MIN && lambda <= PN_SMEL_MAX)) return 0.0;
    double x = lambda - PN_SMEL_MIN;
    int i = (int)x;
    if (i >= PN_SMEL_COUNT - 1) return pn_cie_smel_1nm[PN_SMEL_COUNT - 1];
    double t = x - i;
    return pn_cie_smel_1nm[i] * (1.0 - t) + pn_cie_smel_1nm[i + 1] * t;
}

float pn_swl_melanopic_edi_on(const struct pn_swl *w, vec3 v) {
    const float val[3] = {v.x, v.y, v.z};
    double sum = 0.0;
    for (int i = 0; i < PN_SWL_COUNT; i++) sum += (double)val[i] * pn_cie_smel(w->lambda[i]) * (double)w->inv_pdf[i];
    /* S / (K_m ∫ȳ) is the spectral irradiance in W m^-2 nm^-1 (melanopic.h). */
    return (float)(sum / PN_SWL_COUNT / (PN_K_M * PN_K_MEL_D65 * pn_cie_y_integral()));
}
