/* photometry.h — measured luminaires: IES LM-63 (-1986/-1991/-1995/-2002/-2019) and EULUMDAT
 * files read into one candela table, evaluated by bilinear interpolation in the file's angles
 * with its symmetry, and integrated exactly to lumens.
 *
 * Light space (docs/luminaires.md): nadir (type C gamma = 0, EULUMDAT gamma = 0) is -z, the
 * C = 0 plane contains +x and C = 90 contains +y (C increases counter-clockwise seen from +z,
 * as LM-63 and CIE 121 measure it from above). Type B: photometric zero (H = 0, V = 0) is -z as
 * well, the B-planes turn about the +y axis, H = +90 is +x and V = +90 is +y. */
#ifndef PN_SCENE_PHOTOMETRY_H
#define PN_SCENE_PHOTOMETRY_H

#include "core/error.h"
#include "core/vecmath.h"

#include <stdbool.h>

/* How the stored horizontal angles cover the full circle. */
typedef enum pn_photometry_symmetry {
    PN_PHOTOMETRY_FULL = 0,        /* C 0 .. 360 (the segment last .. 360 wraps to C = 0) */
    PN_PHOTOMETRY_ROTATIONAL = 1,  /* one horizontal angle: the same in every C-plane */
    PN_PHOTOMETRY_QUADRANT = 2,    /* C 0 .. 90, mirrored about the 0-180 and 90-270 planes */
    PN_PHOTOMETRY_HALF_0_180 = 3,  /* C 0 .. 180, mirrored about the 0-180 plane */
    PN_PHOTOMETRY_HALF_90_270 = 4, /* C 90 .. 270, mirrored about the 90-270 plane */
    PN_PHOTOMETRY_B_RANGE = 5      /* type B: H within [first, last], zero outside */
} pn_photometry_symmetry;

typedef enum pn_photometry_type {
    PN_PHOTOMETRY_TYPE_C = 1, /* C-gamma planes about the vertical axis (LM-63 type C, EULUMDAT) */
    PN_PHOTOMETRY_TYPE_B = 2  /* B-beta planes about a horizontal axis (floodlights) */
} pn_photometry_type;

typedef struct pn_photometry {
    pn_photometry_type type;
    pn_photometry_symmetry symmetry;
    bool h_mirrored, v_mirrored; /* type B: H >= 0 (V >= 0) given, the other half mirrored */
    int nv, nh;
    double *v_deg, *h_deg;          /* vertical (gamma / V) and horizontal (C / H) angles, increasing */
    double *cd;                     /* nh x nv candela, cd[h * nv + v], every factor of the file applied */
    double peak_cd;                 /* largest table value: bilinear interpolation never exceeds it */
    double lumens;                  /* the exact integral of the interpolated distribution over the sphere */
    double stated_lumens;           /* IES: lamps x lumens per lamp; EULUMDAT: the lamps' flux; -1 absolute */
    double stated_luminaire_lumens; /* EULUMDAT: lamp flux x light output ratio; else -1 */
    double max_gamma_deg;           /* type C: largest gamma with a non-zero value (180 for type B) */
    int tilt_count;                 /* TILT=INCLUDE: angles (degrees) and multiplying factors */
    double *tilt_deg, *tilt_factor;
    char *path;
    bool eulumdat;
} pn_photometry;

/* Reads an IES (.ies) or EULUMDAT (.ldt) file, chosen by the extension (case-insensitive).
 * `shown` names the file in messages (NULL: path). Bad files: PN_ERROR_BAD_INPUT with
 * "file:line: message"; unreadable files PN_ERROR_IO. *out owns all memory. */
pn_status pn_photometry_read(const char *path, const char *shown, pn_photometry **out, pn_err *err);
/* The same from text already in memory; eulumdat selects the format. */
pn_status pn_photometry_parse(const char *text, size_t length, const char *shown, bool eulumdat, pn_photometry **out,
                              pn_err *err);
void pn_photometry_free(pn_photometry *p);

/* True when the path names a photometric file (.ies or .ldt). */
bool pn_photometry_is_file(const char *path);

/* Candela towards the unit light-space direction w (bilinear in the angles, with the symmetry;
 * zero outside the measured range). */
double pn_photometry_eval(const pn_photometry *p, vec3 w);

/* The multiplying factor of the tilt table at the luminaire's tilt angle (degrees), linear
 * between entries and clamped at the ends; 1 without a table. */
double pn_photometry_tilt_factor(const pn_photometry *p, double tilt_deg);

#endif
