/* wavelengths.h — the wavelengths an eye ray carries in spectral mode.
 *
 * Hero-wavelength sampling (Wilkie et al. 2014, as pbrt-v4 does with four): one uniform number u
 * per pixel sample gives PN_WAVELENGTHS wavelengths, stratified in the cumulative distribution of
 * an importance density over the visible range that follows the sensitivity of the eye,
 *     p(λ) ∝ sech²(a (λ - μ)),  a = 0.0072 / nm,  μ = 538 nm,  on [360, 830] nm
 * (the density pbrt-v4 uses; it is close to ȳ but has no zeros, so every wavelength that
 * contributes to X, Y or Z can be drawn). Its CDF is a tanh, inverted in closed form.
 */
#ifndef PN_SPECTRAL_WAVELENGTHS_H
#define PN_SPECTRAL_WAVELENGTHS_H

#define PN_WAVELENGTHS 4

typedef struct pn_wavelengths {
    float lambda[PN_WAVELENGTHS]; /* nm */
    float pdf[PN_WAVELENGTHS];    /* of each wavelength alone, per nm */
} pn_wavelengths;

/* The importance density of one wavelength, per nm (0 outside [360, 830]). */
double pn_visible_wavelength_pdf(double lambda);

/* The wavelength of CDF value u in [0, 1). */
double pn_visible_wavelength_sample(double u);

/* Both at once: the wavelength of u and 1 / its density (the values of the two functions above). */
void pn_visible_wavelength_sample_inv_pdf(double u, double *lambda, double *inv_pdf);

/* PN_WAVELENGTHS wavelengths from one uniform u in [0, 1): the hero at u, its companions at
 * u + i / PN_WAVELENGTHS (mod 1). */
void pn_wavelengths_sample(double u, pn_wavelengths *out);

#endif
