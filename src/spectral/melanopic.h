/* melanopic.h — CIE S 026 melanopic quantities for lighting design: the melanopic action
 * spectrum s_mel(λ) (melanopic_data.c) and the melanopic equivalent daylight (D65) illuminance
 * (melanopic EDI) of a spectral irradiance.
 *
 * CIE S 026/E:2018: the melanopic irradiance of a spectral irradiance E_e(λ) (W m⁻² nm⁻¹) is
 *     E_mel = ∫ E_e(λ) s_mel(λ) dλ   (W m⁻², over 380–780 nm),
 * and its melanopic EDI is E_mel / K_mel,v^D65 in lux, with K_mel,v^D65 = 1.3262 mW/lm the
 * melanopic efficacy of luminous radiation of D65: so a D65 source of E lux has a melanopic EDI of
 * E lux.
 *
 * penumbra's values are photometric (docs/units.md): a value S(λ) at wavelengths has the
 * illuminance Y = ∫ S ȳ dλ / ∫ ȳ dλ in lux (that is what the film integrates), which is
 * K_m ∫ E_e ȳ dλ for E_e = S / (K_m ∫ ȳ dλ), K_m = 683 lm/W. Hence
 *     EDI = ∫ S(λ) s_mel(λ) dλ / (K_m K_mel,v^D65 ∫ ȳ dλ),
 * estimated from an eye sample's wavelengths (hero sampling) as
 *     (1/n) Σ_i S(λ_i) s_mel(λ_i) / p(λ_i) / (K_m K_mel,v^D65 ∫ ȳ dλ). */
#ifndef PN_SPECTRAL_MELANOPIC_H
#define PN_SPECTRAL_MELANOPIC_H

#include "core/vecmath.h"

#define PN_SMEL_MIN 380.0
#define PN_SMEL_MAX 780.0
#define PN_SMEL_COUNT 401 /* 380..780 nm, 1 nm */

/* K_mel,v^D65 of CIE S 026: 1.3262 mW/lm, in W/lm. */
#define PN_K_MEL_D65 1.3262e-3

extern const double pn_cie_smel_1nm[PN_SMEL_COUNT];

/* s_mel at lambda (nm): linear interpolation of the 1 nm table, 0 outside 380–780 nm (the range
 * of S 026's table and of its integrals). */
double pn_cie_smel(double lambda);

struct pn_swl;
/* The melanopic EDI (lux) of a value v at the active wavelengths w (an irradiance in penumbra's
 * photometric convention, above). */
float pn_swl_melanopic_edi_on(const struct pn_swl *w, vec3 v);

#endif
