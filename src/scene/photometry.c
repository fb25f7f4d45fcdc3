/* photometry.c — the IES LM-63 and EULUMDAT readers, the candela table's bilinear lookup with
 * the file's symmetry, and its exact integral (lumens).
 *
 * IES LM-63 (ANSI/IES LM-63-1995, -2002, -2019; LM-63-1986/-1991 files have no first line and
 * are read the same): an optional "IESNA:LM-63-..." / "IES:LM-63-2019" line, keyword lines
 * ([KEYWORD] text) up to the line starting "TILT=", then numbers separated by blanks, commas or
 * line ends: TILT=INCLUDE's block (lamp-to-luminaire geometry 1-3, the count N, N angles, N
 * factors); lamps, lumens per lamp (-1: absolute photometry), candela multiplier, vertical and
 * horizontal angle counts, photometric type (1 C, 2 B, 3 A), units type, width, length,
 * height; ballast factor, the 1995 ballast-lamp photometric factor (2002: "future use", 2019:
 * the file generation type; neither is a factor, so both are read and not applied), input
 * watts; the vertical angles, the horizontal angles, and the candela values, all vertical
 * angles of the first horizontal angle first. Candela = value x multiplier x ballast factor
 * (x the 1995 ballast-lamp factor). TILT=<file> (a separate tilt file) and type A are refused.
 *
 * Horizontal symmetry (type C), from the first and last horizontal angles as LM-63 defines it:
 * one angle: rotationally symmetric; 0..90: the same in each quadrant; 0..180: symmetric about
 * the 0-180 plane; 90..270: symmetric about the 90-270 plane; 0..360 (or 0 up to a last angle
 * above 180, the remaining segment wrapping to C = 0): none. Type B: H from -90 (or -180) to
 * 90 (180), or from 0, mirrored (H and -H equal); V from -90 to 90, or from 0, mirrored.
 * Vertical angles outside the table give 0 (a downlight measured to 90 degrees is dark above).
 *
 * EULUMDAT (the fixed line layout of Stockmar's format, as AGi32 and DIAL describe it): lines
 * 1-25 the header (line 3 Isym, 4 Mc, 5 Dc, 6 Ng, 7 Dg, 22 DFF, 23 LORL %, 24 the conversion
 * factor for luminous intensities), line 26 the number n of lamp sets and 6 lines per set (26a
 * number of lamps, negative for absolute photometry; 26b type; 26c the total flux of the set's
 * lamps in lm; 26d colour; 26e rendering; 26f watts), 10 direct ratios, Mc C-angles, Ng
 * gamma-angles, then the intensities in cd/klm of the planes Mc1..Mc2 (Isym 0: all Mc; 1: one;
 * 2: C0..C180; 3: C270..C360..C90, i.e. Mc1 = 3 Mc / 4 + 1, Mc2 = Mc1 + Mc / 2 wrapping past
 * C360; 4: C0..C90). Candela = value x flux of lamp set 1 / 1000 x the conversion factor.
 * Isym 3 is stored as the equivalent 90..270 table (I(C) = I(180 - C)).
 *
 * Interpolation: bilinear in (vertical, horizontal) angle, the linear interpolation LM-63 and
 * CIE 102 take between measured angles (RADIANCE's brightdata does the same). The integral of
 * that interpolant is exact cell by cell: on a cell the value is linear along the vertical
 * angle at each horizontal edge and linear between the edges, so with dw = sin g dg dC (type
 * C) or cos V dV dH (type B) each cell is a closed form (cell_integral). */
#include "scene/photometry.h"

#include "core/file.h"

#include "scene/scene.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define PN_PHOT_PI 3.14159265358979323846
#define DEG (PN_PHOT_PI / 180.0)
#define ANGLE_EPS 1e-6

/* ---------------------------------------------------------------- messages and tokens */

typedef struct reader {
    const char *text, *end, *pos;
    int line; /* line of pos (1-based) */
    const char *name;
    pn_err *err;
    int last_line;          /* line of the last token read */
    const char *line_begin; /* first byte of the line pos is on */
    int last_col;           /* 1-based column of the last token read */
} reader;

static pn_status fail(reader *r, int line, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

static pn_status fail(reader *r, int line, const char *fmt, ...) {
    char msg[700];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    /* The column: the last token's where the message is about its line (a value read by
     * next_token), else the line's first column (EULUMDAT's whole-line fields, a header line). */
    int col = line == r->last_line && r->last_col > 0 ? r->last_col : 1;
    return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s:%d:%d: %s", r->name, line, col, msg);
}

/* The next token separated by blanks, commas or line ends; false at the end of the text. */
static bool next_token(reader *r, char *buf, size_t size) {
    while (r->pos < r->end && (isspace((unsigned char)*r->pos) || *r->pos == ',')) {
        if (*r->pos == '\n') {
            r->line++;
            r->line_begin = r->pos + 1;
        }
        r->pos++;
    }
    if (r->pos >= r->end) return false;
    r->last_col = (int)(r->pos - (r->line_begin ? r->line_begin : r->text)) + 1;
    size_t n = 0;
    while (r->pos < r->end && !isspace((unsigned char)*r->pos) && *r->pos != ',') {
        if (n + 1 < size) buf[n++] = *r->pos;
        r->pos++;
    }
    buf[n] = '\0';
    r->last_line = r->line;
    return true;
}

/* Reads one finite number; `what` names it in messages. */
static pn_status read_number(reader *r, const char *what, double *out) {
    char tok[128];
    if (!next_token(r, tok, sizeof tok))
        return fail(r, r->last_line ? r->last_line : r->line, "the file ends before %s (truncated?)", what);
    char *endp = NULL;
    errno = 0;
    double v = strtod(tok, &endp);
    if (endp == tok || *endp != '\0') return fail(r, r->last_line, "%s: expected a number, got \"%s\"", what, tok);
    if (!isfinite(v) || errno == ERANGE) return fail(r, r->last_line, "%s is not a finite number (\"%s\")", what, tok);
    *out = v;
    return PN_OK;
}

static pn_status read_count(reader *r, const char *what, int lo, int hi, int *out) {
    double v = 0.0;
    pn_status st = read_number(r, what, &v);
    if (st != PN_OK) return st;
    if (v != floor(v) || v < lo || v > hi)
        return fail(r, r->last_line, "%s must be a whole number from %d to %d, got %g", what, lo, hi, v);
    *out = (int)v;
    return PN_OK;
}

/* Reads n angles that must increase strictly. */
static pn_status read_angles(reader *r, const char *what, int n, double lo, double hi, double *out) {
    for (int i = 0; i < n; i++) {
        pn_status st = read_number(r, what, &out[i]);
        if (st != PN_OK) return st;
        if (out[i] < lo - ANGLE_EPS || out[i] > hi + ANGLE_EPS)
            return fail(r, r->last_line, "%s %g is outside [%g, %g] degrees", what, out[i], lo, hi);
        if (i > 0 && !(out[i] > out[i - 1]))
            return fail(r, r->last_line, "%s must increase: %g follows %g", what, out[i], out[i - 1]);
    }
    return PN_OK;
}

/* Reads n candela-like values, none negative; scale applied. */
static pn_status read_values(reader *r, int n, double scale, double *out) {
    for (int i = 0; i < n; i++) {
        double v = 0.0;
        char what[96];
        snprintf(what, sizeof what, "candela value %d of %d", i + 1, n);
        pn_status st = read_number(r, what, &v);
        if (st != PN_OK) return st;
        if (v < 0.0) return fail(r, r->last_line, "%s is negative (%g)", what, v);
        out[i] = v * scale;
    }
    return PN_OK;
}

/* ---------------------------------------------------------------- table set-up */

static pn_photometry *photometry_new(const char *name) {
    pn_photometry *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    p->path = strdup(name);
    p->stated_luminaire_lumens = -1.0;
    if (!p->path) {
        free(p);
        return NULL;
    }
    return p;
}

void pn_photometry_free(pn_photometry *p) {
    if (!p) return;
    free(p->v_deg);
    free(p->h_deg);
    free(p->cd);
    free(p->tilt_deg);
    free(p->tilt_factor);
    free(p->path);
    free(p);
}

static bool near_angle(double a, double b) {
    return fabs(a - b) < 1e-4;
}

/* Decides the horizontal symmetry from the first and last angles (LM-63 §, CIE 102). */
static pn_status classify(reader *r, pn_photometry *p, int line) {
    double h0 = p->h_deg[0], h1 = p->h_deg[p->nh - 1], v0 = p->v_deg[0];
    if (p->type == PN_PHOTOMETRY_TYPE_C) {
        if (p->v_deg[0] < -ANGLE_EPS || p->v_deg[p->nv - 1] > 180.0 + ANGLE_EPS)
            return fail(r, line, "type C vertical angles must lie within 0..180 degrees");
        if (p->nh == 1) {
            p->symmetry = PN_PHOTOMETRY_ROTATIONAL;
        } else if (near_angle(h0, 0.0) && near_angle(h1, 90.0)) {
            p->symmetry = PN_PHOTOMETRY_QUADRANT;
        } else if (near_angle(h0, 0.0) && near_angle(h1, 180.0)) {
            p->symmetry = PN_PHOTOMETRY_HALF_0_180;
        } else if (near_angle(h0, 90.0) && near_angle(h1, 270.0)) {
            p->symmetry = PN_PHOTOMETRY_HALF_90_270;
        } else if (near_angle(h0, 0.0) && h1 > 180.0 && h1 <= 360.0 + ANGLE_EPS) {
            p->symmetry = PN_PHOTOMETRY_FULL;
        } else {
            return fail(r, line,
                        "type C horizontal angles from %g to %g match no LM-63 symmetry (one angle, or 0 to 90, "
                        "0 to 180, 90 to 270, 0 to 360)",
                        h0, h1);
        }
    } else {
        p->symmetry = PN_PHOTOMETRY_B_RANGE;
        p->h_mirrored = near_angle(h0, 0.0) && p->nh > 1;
        p->v_mirrored = near_angle(v0, 0.0);
        if (p->nh == 1) return fail(r, line, "type B photometry needs at least two horizontal angles");
        if (h0 < -180.0 - ANGLE_EPS || h1 > 180.0 + ANGLE_EPS)
            return fail(r, line, "type B horizontal angles must lie within -180..180 degrees");
        if (v0 < -90.0 - ANGLE_EPS || p->v_deg[p->nv - 1] > 90.0 + ANGLE_EPS)
            return fail(r, line, "type B vertical angles must lie within -90..90 degrees");
        if (!p->h_mirrored && h0 > ANGLE_EPS)
            return fail(r, line, "type B horizontal angles must start at 0 (mirrored) or below it, not at %g", h0);
        if (!p->v_mirrored && v0 > ANGLE_EPS)
            return fail(r, line, "type B vertical angles must start at 0 (mirrored) or below it, not at %g", v0);
    }
    return PN_OK;
}

/* The exact integral over one cell of the bilinear interpolant: vertical angles a0..a1
 * (radians) with the values along the two horizontal edges averaged (linear between the
 * edges, so the horizontal integral is the mean times the width dh), and weight sin (type C:
 * dw = sin g dg dC) or cos (type B: dw = cos V dV dH). */
static double cell_integral(double a0, double a1, double f0, double f1, double dh, bool type_b) {
    double da = a1 - a0;
    if (!(da > 0.0)) return 0.0;
    double m0, m1; /* int w(a) da and int (a - a0) w(a) da over [a0, a1] */
    if (!type_b) {
        m0 = cos(a0) - cos(a1);
        m1 = (sin(a1) - a1 * cos(a1)) - (sin(a0) - a0 * cos(a0)) - a0 * m0;
    } else {
        m0 = sin(a1) - sin(a0);
        m1 = (cos(a1) + a1 * sin(a1)) - (cos(a0) + a0 * sin(a0)) - a0 * m0;
    }
    return dh * (f0 * m0 + (f1 - f0) / da * m1);
}

static double table_integral(const pn_photometry *p) {
    const int nv = p->nv, nh = p->nh;
    bool type_b = p->type == PN_PHOTOMETRY_TYPE_B;
    double sum = 0.0;
    /* Columns i and i + 1 (the last full-circle segment wraps to column 0 at 360 degrees). */
    int segments = nh - 1;
    bool wrap = p->symmetry == PN_PHOTOMETRY_FULL && p->h_deg[nh - 1] < 360.0 - 1e-4;
    if (wrap) segments++;
    if (p->symmetry == PN_PHOTOMETRY_ROTATIONAL) segments = 1;
    for (int s = 0; s < segments; s++) {
        int i0, i1;
        double dh;
        if (p->symmetry == PN_PHOTOMETRY_ROTATIONAL) {
            i0 = i1 = 0;
            dh = 2.0 * PN_PHOT_PI;
        } else {
            i0 = s;
            i1 = s + 1 < nh ? s + 1 : 0;
            double h1 = s + 1 < nh ? p->h_deg[s + 1] : p->h_deg[0] + 360.0;
            dh = (h1 - p->h_deg[s]) * DEG;
        }
        for (int j = 0; j + 1 < nv; j++) {
            double f0 = 0.5 * (p->cd[(size_t)i0 * nv + j] + p->cd[(size_t)i1 * nv + j]);
            double f1 = 0.5 * (p->cd[(size_t)i0 * nv + j + 1] + p->cd[(size_t)i1 * nv + j + 1]);
            sum += cell_integral(p->v_deg[j] * DEG, p->v_deg[j + 1] * DEG, f0, f1, dh, type_b);
        }
    }
    double copies = 1.0;
    switch (p->symmetry) {
    case PN_PHOTOMETRY_QUADRANT: copies = 4.0; break;
    case PN_PHOTOMETRY_HALF_0_180:
    case PN_PHOTOMETRY_HALF_90_270: copies = 2.0; break;
    case PN_PHOTOMETRY_B_RANGE: copies = (p->h_mirrored ? 2.0 : 1.0) * (p->v_mirrored ? 2.0 : 1.0); break;
    default: break;
    }
    return sum * copies;
}

/* Peak, lumens and the largest lit gamma, once the table is complete. */
static void finish(pn_photometry *p) {
    p->peak_cd = 0.0;
    double max_v = -1.0;
    for (int i = 0; i < p->nh; i++)
        for (int j = 0; j < p->nv; j++) {
            double c = p->cd[(size_t)i * p->nv + j];
            if (c > p->peak_cd) p->peak_cd = c;
            if (c > 0.0) {
                /* a value lights the cells on both sides of its angle */
                double up = j + 1 < p->nv ? p->v_deg[j + 1] : p->v_deg[j];
                if (up > max_v) max_v = up;
            }
        }
    p->max_gamma_deg = p->type == PN_PHOTOMETRY_TYPE_C ? (max_v < 0.0 ? 0.0 : max_v) : 180.0;
    p->lumens = table_integral(p);
}

/* Largest table read: 10^7 values (a 0.1 degree grid over the whole sphere is 6.5 x 10^6). */
#define MAX_TABLE_VALUES 10000000.0

/* Refuses a count of numbers that the rest of the text cannot hold before anything is allocated
 * for them: each number is at least one byte and is separated from the next by another, so n
 * numbers need 2n - 1 bytes; a short file cannot make the reader allocate for a forged count. */
static pn_status check_room(reader *r, double numbers, const char *what) {
    double left = (double)(r->end - r->pos);
    if (2.0 * numbers - 1.0 <= left) return PN_OK;
    return fail(r, r->last_line ? r->last_line : r->line,
                "%.0f %s cannot be stored in the %.0f bytes left in the file (truncated, or a count that is not "
                "the file's)",
                numbers, what, left);
}

static pn_status alloc_table(reader *r, pn_photometry *p) {
    if ((double)p->nv * (double)p->nh > MAX_TABLE_VALUES)
        return fail(r, r->last_line ? r->last_line : r->line,
                    "%d vertical x %d horizontal angles is more than the 10^7 values penumbra reads", p->nv, p->nh);
    pn_status st = check_room(r, (double)p->nv * (double)p->nh, "intensities");
    if (st != PN_OK) return st;
    p->v_deg = malloc((size_t)p->nv * sizeof *p->v_deg);
    p->h_deg = malloc((size_t)p->nh * sizeof *p->h_deg);
    p->cd = malloc((size_t)p->nv * (size_t)p->nh * sizeof *p->cd);
    if (!p->v_deg || !p->h_deg || !p->cd) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    return PN_OK;
}

/* ---------------------------------------------------------------- IES LM-63 */

/* The rest of the current line, from pos; advances past the line end. */
static const char *take_line(reader *r, size_t *len) {
    const char *s = r->pos;
    while (r->pos < r->end && *r->pos != '\n') r->pos++;
    *len = (size_t)(r->pos - s);
    if (r->pos < r->end) {
        r->pos++;
        r->line++;
        r->line_begin = r->pos;
    }
    while (*len > 0 && (s[*len - 1] == '\r' || s[*len - 1] == ' ' || s[*len - 1] == '\t')) (*len)--;
    return s;
}

static pn_status parse_ies(reader *r, pn_photometry *p) {
    /* Header: the version line, keywords, up to TILT=. */
    int version = 1995;
    bool found_tilt = false;
    char tilt[256] = "";
    int tilt_line = 0;
    for (int n = 0; r->pos < r->end; n++) {
        int line = r->line;
        size_t len;
        const char *s = take_line(r, &len);
        while (len > 0 && isspace((unsigned char)*s)) {
            s++;
            len--;
        }
        if (n == 0 && len >= 3 && (unsigned char)s[0] == 0xEF) { /* UTF-8 byte-order mark */
            s += 3;
            len -= 3;
        }
        size_t prefix = (len >= 12 && strncasecmp(s, "IESNA:LM-63-", 12) == 0) ? 12
                        : (len >= 10 && strncasecmp(s, "IES:LM-63-", 10) == 0) ? 10
                                                                               : 0;
        if (n == 0 && prefix) {
            char year[8] = "";
            size_t m = len - prefix < sizeof year - 1 ? len - prefix : sizeof year - 1;
            memcpy(year, s + prefix, m);
            year[m] = '\0';
            version = atoi(year);
            if (version < 100) version += 1900;
            continue;
        }
        if (len >= 5 && strncasecmp(s, "TILT=", 5) == 0) {
            size_t m = len - 5 < sizeof tilt - 1 ? len - 5 : sizeof tilt - 1;
            memcpy(tilt, s + 5, m);
            tilt[m] = '\0';
            tilt_line = line;
            found_tilt = true;
            break;
        }
    }
    if (!found_tilt) return fail(r, r->line, "no \"TILT=\" line: not an IES LM-63 file, or truncated");
    char *t = tilt;
    while (*t == ' ' || *t == '\t') t++;
    if (strcasecmp(t, "INCLUDE") == 0) {
        int geometry, n;
        pn_status st = read_count(r, "the lamp-to-luminaire geometry", 1, 3, &geometry);
        if (st == PN_OK) st = read_count(r, "the number of tilt angles", 1, 100000, &n);
        if (st == PN_OK) st = check_room(r, 2.0 * n, "tilt angles and factors");
        if (st != PN_OK) return st;
        p->tilt_count = n;
        p->tilt_deg = malloc((size_t)n * sizeof *p->tilt_deg);
        p->tilt_factor = malloc((size_t)n * sizeof *p->tilt_factor);
        if (!p->tilt_deg || !p->tilt_factor) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        st = read_angles(r, "tilt angle", n, 0.0, 180.0, p->tilt_deg);
        for (int i = 0; st == PN_OK && i < n; i++) {
            st = read_number(r, "tilt multiplying factor", &p->tilt_factor[i]);
            if (st == PN_OK && p->tilt_factor[i] < 0.0)
                st = fail(r, r->last_line, "tilt multiplying factor %g is negative", p->tilt_factor[i]);
        }
        if (st != PN_OK) return st;
    } else if (strcasecmp(t, "NONE") != 0) {
        return fail(r, tilt_line,
                    "TILT=%s: a separate tilt file is not supported; put its data in the IES file with TILT=INCLUDE",
                    t);
    }

    int lamps, nv, nh, ptype, units;
    double lumens_per_lamp, multiplier, width, length, height, ballast, ballast_lamp, watts;
    pn_status st = read_count(r, "the number of lamps", 0, 1000000, &lamps);
    if (st == PN_OK) st = read_number(r, "the lumens per lamp", &lumens_per_lamp);
    if (st == PN_OK && !(lumens_per_lamp > 0.0 || lumens_per_lamp == -1.0))
        st = fail(r, r->last_line, "the lumens per lamp must be positive, or -1 for absolute photometry (got %g)",
                  lumens_per_lamp);
    if (st == PN_OK) st = read_number(r, "the candela multiplier", &multiplier);
    if (st == PN_OK && !(multiplier > 0.0))
        st = fail(r, r->last_line, "the candela multiplier must be positive (got %g)", multiplier);
    if (st == PN_OK) st = read_count(r, "the number of vertical angles", 2, 100000, &nv);
    if (st == PN_OK) st = read_count(r, "the number of horizontal angles", 1, 100000, &nh);
    if (st == PN_OK) st = read_count(r, "the photometric type", 1, 3, &ptype);
    if (st == PN_OK && ptype == 3)
        st = fail(r, r->last_line, "photometric type A (3) is not supported; convert the file to type C or B");
    if (st == PN_OK) st = read_count(r, "the units type", 1, 2, &units);
    if (st == PN_OK) st = read_number(r, "the luminous width", &width);
    if (st == PN_OK) st = read_number(r, "the luminous length", &length);
    if (st == PN_OK) st = read_number(r, "the luminous height", &height);
    if (st == PN_OK) st = read_number(r, "the ballast factor", &ballast);
    if (st == PN_OK && !(ballast > 0.0))
        st = fail(r, r->last_line, "the ballast factor must be positive (got %g)", ballast);
    if (st == PN_OK) st = read_number(r, "the ballast-lamp photometric factor / file generation type", &ballast_lamp);
    if (st == PN_OK && version < 2002 && !(ballast_lamp > 0.0))
        st = fail(r, r->last_line, "the ballast-lamp photometric factor must be positive (got %g)", ballast_lamp);
    if (st == PN_OK) st = read_number(r, "the input watts", &watts);
    if (st != PN_OK) return st;
    (void)units;
    (void)width;
    (void)length;
    (void)height;
    (void)watts;

    p->type = ptype == 1 ? PN_PHOTOMETRY_TYPE_C : PN_PHOTOMETRY_TYPE_B;
    p->nv = nv;
    p->nh = nh;
    st = alloc_table(r, p);
    if (st != PN_OK) return st;
    bool b = p->type == PN_PHOTOMETRY_TYPE_B;
    st = read_angles(r, "vertical angle", nv, b ? -90.0 : 0.0, b ? 90.0 : 180.0, p->v_deg);
    if (st == PN_OK) st = read_angles(r, "horizontal angle", nh, b ? -180.0 : 0.0, b ? 180.0 : 360.0, p->h_deg);
    if (st == PN_OK) st = classify(r, p, r->last_line);
    double factor = multiplier * ballast * (version < 2002 ? ballast_lamp : 1.0);
    if (st == PN_OK) st = read_values(r, nv * nh, factor, p->cd);
    if (st != PN_OK) return st;
    char extra[64];
    int extra_line = r->line;
    if (next_token(r, extra, sizeof extra))
        return fail(r, r->last_line > extra_line ? r->last_line : extra_line,
                    "unexpected \"%s\" after the %d x %d candela values (inconsistent angle counts?)", extra, nh, nv);
    p->stated_lumens = lumens_per_lamp < 0.0 ? -1.0 : (double)lamps * lumens_per_lamp;
    finish(p);
    return PN_OK;
}

/* ---------------------------------------------------------------- EULUMDAT */

/* Reads header line `want` (1-based) as text into buf. */
static pn_status ldt_line(reader *r, int want, char *buf, size_t size) {
    if (r->pos >= r->end) return fail(r, r->line, "the file ends before line %d (truncated?)", want);
    size_t len;
    const char *s = take_line(r, &len);
    size_t m = len < size - 1 ? len : size - 1;
    memcpy(buf, s, m);
    buf[m] = '\0';
    return PN_OK;
}

static pn_status ldt_number(reader *r, int want, const char *what, double *out) {
    char buf[256];
    int line = r->line;
    pn_status st = ldt_line(r, want, buf, sizeof buf);
    if (st != PN_OK) return st;
    char *s = buf;
    while (isspace((unsigned char)*s)) s++;
    for (char *c = s; *c; c++)
        if (*c == ',') *c = '.'; /* some writers use a decimal comma */
    char *endp = NULL;
    double v = strtod(s, &endp);
    while (endp && isspace((unsigned char)*endp)) endp++;
    if (endp == s || (endp && *endp)) return fail(r, line, "%s: expected a number, got \"%s\"", what, s);
    if (!isfinite(v)) return fail(r, line, "%s is not a finite number", what);
    *out = v;
    return PN_OK;
}

static pn_status ldt_int(reader *r, int want, const char *what, int lo, int hi, int *out) {
    double v = 0.0;
    int line = r->line;
    pn_status st = ldt_number(r, want, what, &v);
    if (st != PN_OK) return st;
    if (v != floor(v) || v < lo || v > hi)
        return fail(r, line, "%s must be a whole number from %d to %d, got %g", what, lo, hi, v);
    *out = (int)v;
    return PN_OK;
}

static pn_status parse_ldt(reader *r, pn_photometry *p) {
    char buf[256];
    pn_status st = ldt_line(r, 1, buf, sizeof buf); /* company */
    int ityp = 0, isym = 0, mc = 0, ng = 0;
    double dc = 0.0, dg = 0.0, lorl = 0.0, cfli = 0.0, tilt = 0.0;
    if (st == PN_OK) st = ldt_int(r, 2, "Ityp (line 2)", 0, 3, &ityp);
    if (st == PN_OK) st = ldt_int(r, 3, "Isym (line 3)", 0, 4, &isym);
    if (st == PN_OK) st = ldt_int(r, 4, "Mc, the number of C-planes (line 4)", 1, 3600, &mc);
    if (st == PN_OK) st = ldt_number(r, 5, "Dc (line 5)", &dc);
    if (st == PN_OK) st = ldt_int(r, 6, "Ng, the number of intensities per C-plane (line 6)", 2, 18001, &ng);
    if (st == PN_OK) st = ldt_number(r, 7, "Dg (line 7)", &dg);
    for (int l = 8; st == PN_OK && l <= 12; l++) st = ldt_line(r, l, buf, sizeof buf);
    for (int l = 13; st == PN_OK && l <= 22; l++) {
        double v;
        st = ldt_number(r, l, "a luminaire dimension or DFF (lines 13-22)", &v);
    }
    if (st == PN_OK) st = ldt_number(r, 23, "LORL, the light output ratio (line 23)", &lorl);
    if (st == PN_OK) st = ldt_number(r, 24, "the conversion factor for luminous intensities (line 24)", &cfli);
    if (st == PN_OK) st = ldt_number(r, 25, "the tilt during measurement (line 25)", &tilt);
    if (st != PN_OK) return st;
    if (!(cfli > 0.0)) return fail(r, 24, "the conversion factor for luminous intensities must be positive");
    if (isym == 2 && mc % 2) return fail(r, 4, "Isym 2 needs an even number of C-planes (Mc = %d)", mc);
    if ((isym == 3 || isym == 4) && mc % 4)
        return fail(r, 4, "Isym %d needs a number of C-planes divisible by 4 (Mc = %d)", isym, mc);
    int sets = 0;
    st = ldt_int(r, 26, "the number of lamp sets (line 26)", 1, 20, &sets);
    double flux = 0.0;
    for (int s = 0; st == PN_OK && s < sets; s++) {
        int line = 27 + 6 * s;
        double n, f, w;
        st = ldt_number(r, line, "the number of lamps (line 26a)", &n);
        if (st == PN_OK) st = ldt_line(r, line + 1, buf, sizeof buf);
        int flux_line = r->line;
        if (st == PN_OK) st = ldt_number(r, line + 2, "the lamps' total luminous flux (line 26c)", &f);
        if (st == PN_OK && s == 0 && !(f > 0.0))
            st = fail(r, flux_line, "the lamps' total luminous flux must be positive (got %g)", f);
        if (st == PN_OK) st = ldt_line(r, line + 3, buf, sizeof buf);
        if (st == PN_OK) st = ldt_line(r, line + 4, buf, sizeof buf);
        if (st == PN_OK) st = ldt_number(r, line + 5, "the wattage (line 26f)", &w);
        /* The lamp count n (26a) is read but not used: 26c is the set's total flux already
         * (and a count far outside int, as a fuzzed file had, must not be converted). */
        (void)n;
        if (s == 0) flux = f;
    }
    if (st != PN_OK) return st;
    /* The rest is numbers, one per line in the format; read them as tokens so that files
     * with several per line are read too. */
    for (int i = 0; st == PN_OK && i < 10; i++) {
        double dr;
        st = read_number(r, "a direct ratio (line 27)", &dr);
    }
    double *c_all = malloc((size_t)mc * sizeof *c_all);
    if (!c_all) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    if (st == PN_OK) st = read_angles(r, "C-angle", mc, 0.0, 360.0, c_all);
    if (st == PN_OK && fabs(c_all[0]) > ANGLE_EPS) st = fail(r, r->last_line, "the C-angles must start at 0");
    int mc1 = 1, mc2 = mc;
    switch (isym) {
    case 1: mc2 = 1; break;
    case 2: mc2 = mc / 2 + 1; break;
    case 3:
        mc1 = 3 * mc / 4 + 1;
        mc2 = mc1 + mc / 2;
        break;
    case 4: mc2 = mc / 4 + 1; break;
    default: break;
    }
    int planes = mc2 - mc1 + 1;
    p->type = PN_PHOTOMETRY_TYPE_C;
    p->nv = ng;
    p->nh = planes;
    if (st == PN_OK) st = alloc_table(r, p);
    if (st == PN_OK) st = read_angles(r, "gamma angle", ng, 0.0, 180.0, p->v_deg);
    double *raw = st == PN_OK ? malloc((size_t)planes * (size_t)ng * sizeof *raw) : NULL;
    if (st == PN_OK && !raw) st = pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    if (st == PN_OK) st = read_values(r, planes * ng, flux / 1000.0 * cfli, raw);
    if (st == PN_OK) {
        char extra[64];
        if (next_token(r, extra, sizeof extra))
            st = fail(r, r->last_line, "unexpected \"%s\" after the %d x %d intensities (inconsistent Mc, Ng or Isym?)",
                      extra, planes, ng);
    }
    if (st == PN_OK) {
        for (int k = 0; k < planes; k++) {
            /* Isym 3: planes C270 .. C360 .. C90 become C90 .. C270 by I(C) = I(180 - C),
             * stored in increasing order (plane k of the file is h index planes - 1 - k). */
            int src = (mc1 - 1 + k) % mc;
            double c = c_all[src];
            int dst = k;
            if (isym == 3) {
                double cc = c > 180.0 ? c - 360.0 : c; /* -90 .. 90 */
                c = 180.0 - cc;                        /* 270 .. 90 */
                dst = planes - 1 - k;
            }
            p->h_deg[dst] = c;
            memcpy(&p->cd[(size_t)dst * ng], &raw[(size_t)k * ng], (size_t)ng * sizeof *raw);
        }
        for (int k = 1; k < planes && st == PN_OK; k++)
            if (!(p->h_deg[k] > p->h_deg[k - 1]))
                st = fail(r, r->last_line, "the C-angles of the stored planes must increase");
        if (st == PN_OK) st = classify(r, p, r->last_line);
    }
    free(raw);
    free(c_all);
    if (st != PN_OK) return st;
    p->stated_lumens = flux;
    p->stated_luminaire_lumens = flux * lorl / 100.0;
    p->eulumdat = true;
    finish(p);
    return PN_OK;
}

/* ---------------------------------------------------------------- entry points */

pn_status pn_photometry_parse(const char *text, size_t length, const char *shown, bool eulumdat, pn_photometry **out,
                              pn_err *err) {
    *out = NULL;
    reader r = {.text = text, .end = text + length, .pos = text, .line = 1, .name = shown, .err = err};
    pn_photometry *p = photometry_new(shown);
    if (!p) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    for (size_t i = 0; i < length; i++)
        if (text[i] == '\0') {
            pn_photometry_free(p);
            return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s:1: a NUL byte: not a text file", shown);
        }
    pn_status st = eulumdat ? parse_ldt(&r, p) : parse_ies(&r, p);
    if (st == PN_OK && !(p->peak_cd > 0.0))
        st = fail(&r, r.line, "every intensity is zero: the luminaire emits nothing");
    if (st != PN_OK) {
        pn_photometry_free(p);
        return st;
    }
    *out = p;
    return PN_OK;
}

static bool has_ext(const char *path, const char *ext) {
    size_t n = strlen(path), m = strlen(ext);
    return n > m && strcasecmp(path + n - m, ext) == 0;
}

bool pn_photometry_is_file(const char *path) {
    return path && (has_ext(path, ".ies") || has_ext(path, ".ldt"));
}

/* The largest photometric file read (256 MiB; real files are kilobytes). */
#define MAX_PHOTOMETRY_FILE_BYTES ((uint64_t)1 << 28)

pn_status pn_photometry_read(const char *path, const char *shown, pn_photometry **out, pn_err *err) {
    *out = NULL;
    if (!shown) shown = path;
    /* Only a regular file within the limit: a FIFO must not block, a device not stream. */
    uint64_t size = 0;
    pn_err why;
    pn_err_init(&why);
    FILE *f = pn_file_open_regular(path, MAX_PHOTOMETRY_FILE_BYTES, &size, &why);
    if (!f) /* a missing or unreadable file is bad input here, as it always was */
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: cannot open the photometric file: %s", shown, why.message);
    char *buf = malloc(size ? (size_t)size : 1);
    size_t len = buf ? fread(buf, 1, (size_t)size, f) : 0;
    bool bad = ferror(f) || (buf && len != size);
    fclose(f);
    if (!buf) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory reading %s", shown);
    if (bad) {
        free(buf);
        return pn_err_set(err, PN_ERROR_IO, "%s: read error", shown);
    }
    pn_status st = pn_photometry_parse(buf, len, shown, has_ext(path, ".ldt"), out, err);
    free(buf);
    return st;
}

/* ---------------------------------------------------------------- evaluation */

/* Index i with a[i] <= x <= a[i + 1] (n >= 2, a[0] <= x <= a[n - 1]) and the fraction. */
static int bracket(const double *a, int n, double x, double *t) {
    int lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (a[mid] <= x)
            lo = mid;
        else
            hi = mid;
    }
    double span = a[lo + 1] - a[lo];
    double f = span > 0.0 ? (x - a[lo]) / span : 0.0;
    *t = f < 0.0 ? 0.0 : (f > 1.0 ? 1.0 : f);
    return lo;
}

/* Linear along the vertical angle in column i. */
static double column(const pn_photometry *p, int i, int j, double tv) {
    const double *c = &p->cd[(size_t)i * p->nv];
    return c[j] + (c[j + 1] - c[j]) * tv;
}

/* Bilinear lookup at table angles (v, h) already folded into the stored ranges; h_wrap: the
 * full-circle segment from the last angle to 360 (column 0). */
static double lookup(const pn_photometry *p, double v, double h) {
    if (v < p->v_deg[0] - ANGLE_EPS || v > p->v_deg[p->nv - 1] + ANGLE_EPS) return 0.0;
    double tv;
    int j = bracket(p->v_deg, p->nv, v, &tv);
    if (p->symmetry == PN_PHOTOMETRY_ROTATIONAL) return column(p, 0, j, tv);
    int last = p->nh - 1;
    if (p->symmetry == PN_PHOTOMETRY_FULL && h > p->h_deg[last]) {
        double span = p->h_deg[0] + 360.0 - p->h_deg[last];
        double th = span > 0.0 ? (h - p->h_deg[last]) / span : 0.0;
        th = th > 1.0 ? 1.0 : th;
        return column(p, last, j, tv) * (1.0 - th) + column(p, 0, j, tv) * th;
    }
    if (h < p->h_deg[0] - ANGLE_EPS || h > p->h_deg[last] + ANGLE_EPS) return 0.0;
    double th;
    int i = bracket(p->h_deg, p->nh, h, &th);
    return column(p, i, j, tv) * (1.0 - th) + column(p, i + 1, j, tv) * th;
}

double pn_photometry_eval(const pn_photometry *p, vec3 w) {
    double x = w.x, y = w.y, z = w.z;
    double len = sqrt(x * x + y * y + z * z);
    if (!(len > 0.0)) return 0.0;
    x /= len;
    y /= len;
    z /= len;
    if (p->type == PN_PHOTOMETRY_TYPE_B) {
        double v = asin(y < -1.0 ? -1.0 : (y > 1.0 ? 1.0 : y)) / DEG;
        double h = atan2(x, -z) / DEG;
        if (p->h_mirrored) h = fabs(h);
        if (p->v_mirrored) v = fabs(v);
        return lookup(p, v, h);
    }
    double gamma = acos(-z < -1.0 ? -1.0 : (-z > 1.0 ? 1.0 : -z)) / DEG;
    double c = atan2(y, x) / DEG;
    if (c < 0.0) c += 360.0;
    switch (p->symmetry) {
    case PN_PHOTOMETRY_QUADRANT:
        if (c > 180.0) c = 360.0 - c;
        if (c > 90.0) c = 180.0 - c;
        break;
    case PN_PHOTOMETRY_HALF_0_180:
        if (c > 180.0) c = 360.0 - c;
        break;
    case PN_PHOTOMETRY_HALF_90_270:
        if (c < 90.0)
            c = 180.0 - c;
        else if (c > 270.0)
            c = 540.0 - c;
        break;
    default: break;
    }
    return lookup(p, gamma, c);
}

double pn_photometry_tilt_factor(const pn_photometry *p, double tilt_deg) {
    if (!p->tilt_count) return 1.0;
    if (p->tilt_count == 1 || tilt_deg <= p->tilt_deg[0]) return p->tilt_factor[0];
    if (tilt_deg >= p->tilt_deg[p->tilt_count - 1]) return p->tilt_factor[p->tilt_count - 1];
    double t;
    int i = bracket(p->tilt_deg, p->tilt_count, tilt_deg, &t);
    return p->tilt_factor[i] + (p->tilt_factor[i + 1] - p->tilt_factor[i]) * t;
}

/* ---------------------------------------------------------------- the scene's luminaires */

static const pn_light_def *luminaire_def(pn_scene scene, uint32_t index) {
    uint32_t k = 0;
    for (int i = 0; scene && i < scene->light_def_count; i++)
        if (scene->light_defs[i].photometry >= 0 && k++ == index) return &scene->light_defs[i];
    return NULL;
}

uint32_t pn_scene_luminaire_count(pn_scene scene) {
    uint32_t n = 0;
    for (int i = 0; scene && i < scene->light_def_count; i++) n += scene->light_defs[i].photometry >= 0;
    return n;
}

pn_status pn_scene_luminaire_get(pn_scene scene, uint32_t index, pn_luminaire_info *info) {
    const pn_light_def *d = luminaire_def(scene, index);
    if (!d || !info) return PN_ERROR_INVALID_ARGUMENT;
    const pn_photometry *p = scene->photometries[d->photometry];
    info->file = p->path;
    info->source = d->source ? d->source : "";
    info->file_lumens = p->lumens;
    info->lumens = p->lumens * d->photometry_scale;
    info->stated_lumens = p->stated_lumens;
    info->stated_luminaire_lumens = p->stated_luminaire_lumens;
    info->peak_candela = p->peak_cd * d->photometry_scale;
    return PN_OK;
}
