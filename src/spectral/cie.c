/* cie.c — evaluation of the CIE tables and the colour conversions declared in cie.h. */
#include "spectral/cie.h"

#include <math.h>
#include <string.h>

const pn_cie_illuminant *pn_cie_illuminant_named(const char *name) {
    for (int i = 0; i < PN_CIE_ILLUMINANT_COUNT; i++)
        if (strcmp(pn_cie_illuminants[i].name, name) == 0) return &pn_cie_illuminants[i];
    return NULL;
}

double pn_cie_table_eval(const double table[PN_CIE_TABLE_COUNT], double lambda) {
    if (!(lambda >= PN_LAMBDA_MIN && lambda <= PN_LAMBDA_MAX)) return 0.0;
    double x = (lambda - PN_LAMBDA_MIN) / 5.0;
    int i = (int)x;
    if (i >= PN_CIE_TABLE_COUNT - 1) return table[PN_CIE_TABLE_COUNT - 1];
    double t = x - i;
    return table[i] * (1.0 - t) + table[i + 1] * t;
}

/* pn_cie_table_eval's formula for the three tables with one index computation (the same
 * numbers; pn_swl_sample calls it for every wavelength drawn). */
void pn_cie_xyz_bar(double lambda, double xyz_bar[3]) {
    const double *tab[3] = {pn_cie_x_5nm, pn_cie_y_5nm, pn_cie_z_5nm};
    if (!(lambda >= PN_LAMBDA_MIN && lambda <= PN_LAMBDA_MAX)) {
        xyz_bar[0] = xyz_bar[1] = xyz_bar[2] = 0.0;
        return;
    }
    double x = (lambda - PN_LAMBDA_MIN) / 5.0;
    int i = (int)x;
    if (i >= PN_CIE_TABLE_COUNT - 1) {
        for (int k = 0; k < 3; k++) xyz_bar[k] = tab[k][PN_CIE_TABLE_COUNT - 1];
        return;
    }
    double t = x - i;
    for (int k = 0; k < 3; k++) xyz_bar[k] = tab[k][i] * (1.0 - t) + tab[k][i + 1] * t;
}

double pn_cie_y_integral(void) {
    /* The trapezoid rule is exact for a piecewise linear function sampled at its knots. */
    double sum = 0.0;
    for (int i = 0; i + 1 < PN_CIE_TABLE_COUNT; i++) sum += 0.5 * (pn_cie_y_5nm[i] + pn_cie_y_5nm[i + 1]) * 5.0;
    return sum;
}

double pn_planck(double lambda, double kelvin) {
    if (kelvin <= 0.0) return 0.0;
    const double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
    double l = lambda * 1e-9;
    return (2.0 * h * c * c) / (l * l * l * l * l * expm1((h * c) / (l * kb * kelvin)));
}

/* The Rec. 709 / sRGB matrices (IEC 61966-2-1), D65 white normalised to Y = 1. */
void pn_xyz_to_linear_srgb(const double xyz[3], double rgb[3]) {
    rgb[0] = 3.2404542 * xyz[0] - 1.5371385 * xyz[1] - 0.4985314 * xyz[2];
    rgb[1] = -0.9692660 * xyz[0] + 1.8760108 * xyz[1] + 0.0415560 * xyz[2];
    rgb[2] = 0.0556434 * xyz[0] - 0.2040259 * xyz[1] + 1.0572252 * xyz[2];
}

void pn_linear_srgb_to_xyz(const double rgb[3], double xyz[3]) {
    xyz[0] = 0.4124564 * rgb[0] + 0.3575761 * rgb[1] + 0.1804375 * rgb[2];
    xyz[1] = 0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2];
    xyz[2] = 0.0193339 * rgb[0] + 0.1191920 * rgb[1] + 0.9503041 * rgb[2];
}

/* CIE 1976 L*a*b*: the cube root with its linear segment below (6/29)^3. */
static double lab_f(double t) {
    const double d = 6.0 / 29.0;
    return t > d * d * d ? cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

void pn_xyz_to_lab(const double xyz[3], const double white_xyz[3], double lab[3]) {
    double fx = lab_f(xyz[0] / white_xyz[0]);
    double fy = lab_f(xyz[1] / white_xyz[1]);
    double fz = lab_f(xyz[2] / white_xyz[2]);
    lab[0] = 116.0 * fy - 16.0;
    lab[1] = 500.0 * (fx - fy);
    lab[2] = 200.0 * (fy - fz);
}
