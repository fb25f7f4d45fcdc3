/* false_color.c — false-colour pictures: of statistics layers with a colour bar (the IAS paper's
 * Figs. 9 and 11: passes per pixel, visible fraction, ...), and for lighting analysis with a
 * legend in real units, linear or logarithmic, smooth, in bands or as contour lines, after the
 * conventions of RADIANCE's falsecolor (its options -s, -m, -log, -n, -cl, -cb and -l; the
 * legend at the left, one box per division, the label above). Text is drawn with a 3x5-pixel
 * font of digits, "-.e+", and the letters and signs units need, so that the picture says what its
 * colours mean without a font library. */
#include "core/context.h"
#include "io/image.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <string.h>

/* Blue (low) - cyan - green - yellow - red (high), linear between five stops, in linear RGB. */
static void color_of(double t, float rgb[3]) {
    static const float stops[5][3] = {
        {0.0f, 0.0f, 0.8f}, {0.0f, 0.7f, 0.9f}, {0.0f, 0.8f, 0.0f}, {0.9f, 0.9f, 0.0f}, {0.9f, 0.0f, 0.0f}};
    if (!(t >= 0.0)) t = 0.0; /* NaN too */
    if (t > 1.0) t = 1.0;
    double x = t * 4.0;
    int i = x >= 4.0 ? 3 : (int)x;
    float f = (float)(x - (double)i);
    for (int c = 0; c < 3; c++) rgb[c] = stops[i][c] + (stops[i + 1][c] - stops[i][c]) * f;
}

/* 3x5 glyphs for digits, "-.e+" and the letters and signs of unit labels, one row per 3 bits
 * (bit 2 = left column). */
#define GLYPHS "0123456789-.e+luxcdm/%nitsDFaLkor "
static int glyph(char ch, unsigned char rows[5]) {
    static const char *chars = GLYPHS;
    static const unsigned char font[sizeof GLYPHS - 1][5] = {
        {7, 5, 5, 5, 7},
        {2, 6, 2, 2, 7},
        {7, 1, 7, 4, 7},
        {7, 1, 7, 1, 7},
        {5, 5, 7, 1, 1},
        {7, 4, 7, 1, 7},
        {7, 4, 7, 5, 7},
        {7, 1, 1, 1, 1},
        {7, 5, 7, 5, 7},
        {7, 5, 7, 1, 7},
        {0, 0, 7, 0, 0},
        {0, 0, 0, 0, 2},
        {0, 7, 5, 6, 3},
        {0, 2, 7, 2, 0},
        /* l u x c d m / % */
        {6, 2, 2, 2, 7},
        {0, 5, 5, 5, 7},
        {0, 5, 2, 2, 5},
        {0, 7, 4, 4, 7},
        {1, 1, 7, 5, 7},
        {0, 0, 7, 7, 5},
        {1, 1, 2, 4, 4},
        {5, 1, 2, 4, 5},
        /* n i t s D F a L k o r, space */
        {0, 0, 6, 5, 5},
        {2, 0, 2, 2, 2},
        {2, 7, 2, 2, 3},
        {3, 4, 2, 1, 6},
        {6, 5, 5, 5, 6},
        {7, 4, 6, 4, 4},
        {0, 6, 1, 7, 7},
        {4, 4, 4, 4, 7},
        {4, 5, 6, 5, 5},
        {0, 0, 7, 5, 7},
        {0, 0, 7, 4, 4},
        {0, 0, 0, 0, 0},
    };
    const char *at = strchr(chars, ch);
    if (!at || !ch) return 0;
    memcpy(rows, font[at - chars], 5);
    return 1;
}

/* Draws text in white with its top-left corner at (x, y), scaled by `scale`. */
static void draw_text(float *rgb, int w, int h, int x, int y, int scale, const char *text) {
    for (const char *c = text; *c; c++, x += 4 * scale) {
        unsigned char rows[5];
        if (!glyph(*c, rows)) continue;
        for (int r = 0; r < 5; r++)
            for (int col = 0; col < 3; col++) {
                if (!(rows[r] & (4 >> col))) continue;
                for (int sy = 0; sy < scale; sy++)
                    for (int sx = 0; sx < scale; sx++) {
                        int px = x + col * scale + sx, py = y + r * scale + sy;
                        if (px < 0 || py < 0 || px >= w || py >= h) continue;
                        float *p = rgb + 3 * ((size_t)py * (size_t)w + (size_t)px);
                        p[0] = p[1] = p[2] = 1.0f;
                    }
            }
    }
}

pn_status pn_image_false_color(pn_context ctx, pn_image image, const char *layer, double vmin, double vmax,
                               pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !image || !layer || !out_image) return PN_ERROR_INVALID_ARGUMENT;
    const pn_image_layer *src = NULL;
    for (int l = 0; l < image->layer_count; l++)
        if (strcmp(image->layers[l].name, layer) == 0) src = &image->layers[l];
    if (!src || src->channels != 1)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "image has no single-channel layer \"%s\"", layer);
    const int w = image->width, h = image->height;
    const size_t n = (size_t)w * (size_t)h;
    if (!(vmax > vmin)) {
        vmin = INFINITY;
        vmax = -INFINITY;
        for (size_t i = 0; i < n; i++) {
            double v = (double)src->data[i];
            if (!isfinite(v)) continue;
            vmin = fmin(vmin, v);
            vmax = fmax(vmax, v);
        }
        if (!isfinite(vmin)) vmin = vmax = 0.0;
        if (!(vmax > vmin)) vmax = vmin + 1.0;
    }
    /* Below the picture: a gap, the bar, and a line for its end values. */
    const int scale = w >= 256 ? 2 : 1;
    const int gap = 2 * scale, bar = 8 * scale, text = 7 * scale;
    const int out_h = h + gap + bar + text;
    pn_image out = pn_image_create(w, out_h);
    if (!out) return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", w, out_h);
    float *rgb = out->layers[0].data;
    for (size_t i = 0; i < n; i++) color_of(((double)src->data[i] - vmin) / (vmax - vmin), rgb + 3 * i);
    for (int y = h + gap; y < h + gap + bar; y++)
        for (int x = 0; x < w; x++)
            color_of(w > 1 ? (double)x / (double)(w - 1) : 0.0, rgb + 3 * ((size_t)y * (size_t)w + (size_t)x));
    char lo[32], hi[32];
    snprintf(lo, sizeof lo, "%.3g", vmin);
    snprintf(hi, sizeof hi, "%.3g", vmax);
    int ty = h + gap + bar + scale;
    draw_text(rgb, w, out_h, scale, ty, scale, lo);
    draw_text(rgb, w, out_h, w - (int)strlen(hi) * 4 * scale, ty, scale, hi);
    *out_image = out;
    return PN_OK;
}

/* ---- lighting analysis: RADIANCE falsecolor's conventions ------------------------------------ */

/* falsecolor's default palette runs from dark purple through blue, green and red to yellow;
 * these stops are ours, linear in t. */
static void design_color(double t, float rgb[3]) {
    static const float stops[5][3] = {
        {0.25f, 0.0f, 0.35f}, {0.0f, 0.1f, 0.9f}, {0.0f, 0.75f, 0.1f}, {0.9f, 0.05f, 0.0f}, {1.0f, 1.0f, 0.0f}};
    if (!(t >= 0.0)) t = 0.0;
    if (t > 1.0) t = 1.0;
    double x = t * 4.0;
    int i = x >= 4.0 ? 3 : (int)x;
    float f = (float)(x - (double)i);
    for (int c = 0; c < 3; c++) rgb[c] = stops[i][c] + (stops[i + 1][c] - stops[i][c]) * f;
}

typedef struct scale_map {
    double top;  /* the scale */
    int decades; /* 0: linear */
    int divisions;
} scale_map;

/* The position of value v on the scale, in [0, 1] (below 0 and NaN: 0). */
static double scale_position(const scale_map *m, double v) {
    if (!(v > 0.0)) return 0.0;
    double t = m->decades > 0 ? (log10(v / m->top) + (double)m->decades) / (double)m->decades : v / m->top;
    return t < 0.0 ? 0.0 : t > 1.0 ? 1.0 : t;
}

/* The value at position t of the scale. */
static double scale_value(const scale_map *m, double t) {
    return m->decades > 0 ? m->top * pow(10.0, (t - 1.0) * (double)m->decades) : m->top * t;
}

static int band_of(const scale_map *m, double t) {
    int b = (int)(t * (double)m->divisions);
    return b >= m->divisions ? m->divisions - 1 : b;
}

/* A legend number in at most 6 characters: "1200", "0.25", "3.5e4". */
static void format_value(double v, char *buf, size_t size) {
    if (v == 0.0)
        snprintf(buf, size, "0");
    else if (fabs(v) >= 1e5 || fabs(v) < 1e-2)
        snprintf(buf, size, "%.1e", v);
    else
        snprintf(buf, size, "%.4g", v);
    /* "3.5e+04" -> "3.5e4" */
    char *e = strchr(buf, 'e');
    if (e) {
        char *q = e + 1;
        int neg = *q == '-';
        if (*q == '+' || *q == '-') q++;
        while (*q == '0' && q[1]) q++;
        memmove(e + 1 + neg, q, strlen(q) + 1);
        if (neg) e[1] = '-';
    }
}

static void fill_rect(float *rgb, int w, int h, int x0, int y0, int x1, int y1, const float c[3]) {
    for (int y = y0 < 0 ? 0 : y0; y < y1 && y < h; y++)
        for (int x = x0 < 0 ? 0 : x0; x < x1 && x < w; x++)
            memcpy(rgb + 3 * ((size_t)y * (size_t)w + (size_t)x), c, 12);
}

pn_status pn_image_false_color_legend(pn_context ctx, pn_image image, const char *layer,
                                      const pn_false_color_options *options, pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !image || !layer || !out_image) return PN_ERROR_INVALID_ARGUMENT;
    pn_false_color_options o = {0};
    if (options) o = *options;
    const pn_image_layer *src = NULL;
    for (int l = 0; l < image->layer_count; l++)
        if (strcmp(image->layers[l].name, layer) == 0) src = &image->layers[l];
    if (!src || src->channels != 1)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "image has no single-channel layer \"%s\"", layer);
    if (o.divisions < 0 || o.divisions > 64 || o.log_decades < 0 || o.log_decades > 20 || !(o.multiplier >= 0.0) ||
        !isfinite(o.scale) || !isfinite(o.multiplier))
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                               "false colour: divisions 1..64, decades 0..20, a finite scale and multiplier");
    const double mult = o.multiplier > 0.0 ? o.multiplier : 1.0;
    const int w = image->width, h = image->height;
    const size_t n = (size_t)w * (size_t)h;
    scale_map m = {o.scale, o.log_decades, o.divisions > 0 ? o.divisions : 8};
    if (!(m.top > 0.0)) { /* falsecolor -s auto: the maximum */
        m.top = 0.0;
        for (size_t i = 0; i < n; i++) {
            double v = (double)src->data[i] * mult;
            if (isfinite(v) && v > m.top) m.top = v;
        }
        if (!(m.top > 0.0)) m.top = 1.0;
    }
    /* Layout: the legend at the left (RADIANCE's), boxes from the top value down. */
    const int s = h >= 256 ? 2 : 1; /* font scale */
    const int char_w = 4 * s, text_h = 5 * s, pad = 3 * s;
    const int legend_w = 2 * pad + 6 * char_w + 10 * s;
    const int out_h = h > 128 ? h : 128, out_w = w + legend_w;
    pn_image out = pn_image_create(out_w, out_h);
    if (!out) return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", out_w, out_h);
    float *rgb = out->layers[0].data; /* zeroed: black */
    /* The picture. */
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            double t = scale_position(&m, (double)src->data[i] * mult);
            float c[3] = {0, 0, 0};
            if (o.style == PN_FALSE_COLOR_SMOOTH) {
                design_color(t, c);
            } else {
                int b = band_of(&m, t);
                bool edge = false;
                if (o.style == PN_FALSE_COLOR_LINES) {
                    /* A contour line where the band changes towards the right or lower neighbour. */
                    if (x + 1 < w) edge |= band_of(&m, scale_position(&m, (double)src->data[i + 1] * mult)) != b;
                    if (y + 1 < h)
                        edge |= band_of(&m, scale_position(&m, (double)src->data[i + (size_t)w] * mult)) != b;
                }
                if (o.style == PN_FALSE_COLOR_BANDS || edge) design_color(((double)b + 0.5) / (double)m.divisions, c);
            }
            memcpy(rgb + 3 * ((size_t)y * (size_t)out_w + (size_t)(legend_w + x)), c, 12);
        }
    /* The legend: the label, then one box per division with its lower value. */
    int y = pad;
    if (o.label && o.label[0]) {
        draw_text(rgb, out_w, out_h, pad, y, s, o.label);
        y += text_h + pad;
    }
    const int box_h = (out_h - y - pad) / m.divisions;
    const int box_w = 8 * s;
    for (int k = 0; k < m.divisions; k++) {
        int b = m.divisions - 1 - k; /* highest at the top */
        float c[3];
        design_color(((double)b + 0.5) / (double)m.divisions, c);
        int y0 = y + k * box_h;
        fill_rect(rgb, out_w, out_h, pad, y0, pad + box_w, y0 + box_h - s, c);
        char num[32];
        format_value(scale_value(&m, (double)b / (double)m.divisions), num, sizeof num);
        draw_text(rgb, out_w, out_h, pad + box_w + 2 * s, y0 + box_h - s - text_h, s, num);
    }
    *out_image = out;
    return PN_OK;
}

pn_status pn_image_from_values(pn_context ctx, int width, int height, const char *layer, const float *values,
                               pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !layer || !values || !out_image || width <= 0 || height <= 0 || width > 65536 || height > 65536)
        return ctx ? pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_image_from_values: bad arguments")
                   : PN_ERROR_INVALID_ARGUMENT;
    pn_image img = pn_image_create(width, height);
    float *dst = img ? pn_image_add_layer(img, layer, 1) : NULL;
    if (!dst) {
        pn_image_free(img);
        return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", width, height);
    }
    memcpy(dst, values, (size_t)width * (size_t)height * sizeof *dst);
    *out_image = img;
    return PN_OK;
}
