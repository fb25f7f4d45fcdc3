/* cie.h — the colorimetric data and conversions of penumbra's spectral mode: the CIE 1931 2°
 * colour matching functions, the CIE illuminants D65 and A, Planck's law, and the XYZ <-> linear
 * sRGB (Rec. 709 primaries, D65 white) matrices.
 *
 * Wavelengths are in nanometres over [PN_LAMBDA_MIN, PN_LAMBDA_MAX], the range of the CIE 1931
 * tables (360–830 nm, as pbrt-v4's). The tables are the CIE's own 5 nm values (cie_data.c);
 * between the tabulated wavelengths they are interpolated linearly, and they are 0 outside.
 */
#ifndef PN_SPECTRAL_CIE_H
#define PN_SPECTRAL_CIE_H

#define PN_LAMBDA_MIN 360.0
#define PN_LAMBDA_MAX 830.0
#define PN_CIE_TABLE_COUNT 95 /* (830 - 360) / 5 + 1 */

extern const double pn_cie_x_5nm[PN_CIE_TABLE_COUNT];
extern const double pn_cie_y_5nm[PN_CIE_TABLE_COUNT];
extern const double pn_cie_z_5nm[PN_CIE_TABLE_COUNT];
extern const double pn_cie_d65_5nm[PN_CIE_TABLE_COUNT];
extern const double pn_cie_a_5nm[PN_CIE_TABLE_COUNT];

/* The named illuminants of pbrt-v4 (stdillum-A, -D50, -D65, -F1 ... -F12, illum-acesD60) as the
 * CIE tabulates them: `count` values every 5 nm from `lambda_min` (360 nm for D65 and A, 380 nm
 * for the others, whose CIE tables cover 380–780 nm), relative power (any scale: uses normalise).
 * ACES D60 is CIE daylight at the ACES white (x 0.32168, y 0.33767, SMPTE ST 2065-1), computed by
 * scripts/gen_cie_tables.py from the CIE's D50, D55 and D65 tables. */
#define PN_CIE_ILLUMINANT_COUNT 16

typedef struct pn_cie_illuminant {
    const char *name; /* pbrt-v4's name */
    double lambda_min;
    int count;
    const double *value;
} pn_cie_illuminant;

extern const pn_cie_illuminant pn_cie_illuminants[PN_CIE_ILLUMINANT_COUNT];

/* The named illuminant `name`, or NULL. */
const pn_cie_illuminant *pn_cie_illuminant_named(const char *name);

/* A tabulated 5 nm function at lambda (nm): linear interpolation, 0 outside the table. */
double pn_cie_table_eval(const double table[PN_CIE_TABLE_COUNT], double lambda);

/* The colour matching functions x̄, ȳ, z̄ at lambda (nm). */
void pn_cie_xyz_bar(double lambda, double xyz_bar[3]);

/* ∫ ȳ(λ) dλ over [PN_LAMBDA_MIN, PN_LAMBDA_MAX] of the interpolated table (106.857 nm for the
 * CIE 1931 data; exact for the piecewise linear function). */
double pn_cie_y_integral(void);

/* Luminous efficacy of radiation at 555 nm: 683 lm/W (the SI definition of the candela). */
#define PN_K_M 683.0

/* Planck's law: spectral radiance of a black body at temperature kelvin (K) and wavelength
 * lambda (nm), in W / (m² sr m). 0 for kelvin <= 0. */
double pn_planck(double lambda, double kelvin);

/* CIE XYZ <-> linear sRGB (Rec. 709 primaries, D65 white point, Y of white = 1). */
void pn_xyz_to_linear_srgb(const double xyz[3], double rgb[3]);
void pn_linear_srgb_to_xyz(const double rgb[3], double xyz[3]);

/* CIE 1976 L*a*b* of XYZ relative to the white point white_xyz. */
void pn_xyz_to_lab(const double xyz[3], const double white_xyz[3], double lab[3]);

#endif
