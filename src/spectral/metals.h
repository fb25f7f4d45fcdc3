/* metals.h — tabulated optical constants of conductors for spectral mode: the index of refraction
 * eta(lambda) and extinction coefficient k(lambda) of the named spectra that scenes use for
 * metals (pbrt-v4's metal-Ag-* and metal-Cu-*), and the conductor's reflectance at normal
 * incidence from them.
 *
 * penumbra's conductor model is a Blinn lobe (or a mirror) whose reflectance is the conductor's
 * Fresnel reflectance at normal incidence, F0 = ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2) (scene/
 * materials.c). RGB mode takes F0 of eta and k at 630, 532 and 465 nm; spectral mode evaluates it
 * at each sampled wavelength from these tables (pn_bsdf_at_spectral). Other metal names keep
 * their RGB F0, upsampled as a reflectance. */
#ifndef PN_SPECTRAL_METALS_H
#define PN_SPECTRAL_METALS_H

#define PN_METAL_SAMPLES 56
#define PN_METAL_TABLE_COUNT 4

typedef struct pn_metal_table {
    const char *name;
    const double *lambda; /* PN_METAL_SAMPLES wavelengths (nm), increasing */
    const double *value;
} pn_metal_table;

extern const pn_metal_table pn_metal_tables[PN_METAL_TABLE_COUNT];

/* The table of named spectrum `name`, or NULL. */
const pn_metal_table *pn_metal_table_named(const char *name);

/* Table t at lambda (nm): linear interpolation, end values held outside (pn_table_eval). */
double pn_metal_eval(const pn_metal_table *t, double lambda);

/* The Fresnel reflectance at normal incidence of a conductor of index eta and extinction k. */
static inline double pn_conductor_f0(double eta, double k) {
    double num = (eta - 1.0) * (eta - 1.0) + k * k, den = (eta + 1.0) * (eta + 1.0) + k * k;
    return den > 0.0 ? num / den : 1.0;
}

#endif
