/* false_color.c — false-colour pictures of statistics layers with a colour bar (the IAS paper's
 * Figs. 9 and 11: passes per pixel, visible fraction, ...). The bar's end values are drawn with a
 * 3x5-pixel digit font so that the picture says what its colours mean. */
#include "core/context.h"
#include "io/image.h"

#include <math.h>
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

/* 3x5 glyphs for digits and "-.e+", one row per 3 bits (bit 2 = left column). */
static int glyph(char ch, unsigned char rows[5]) {
    static const char *chars = "0123456789-.e+";
    static const unsigned char font[14][5] = {
        {7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7}, {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1},
        {7, 4, 7, 1, 7}, {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7}, {7, 5, 7, 1, 7},
        {0, 0, 7, 0, 0}, {0, 0, 0, 0, 2}, {0, 7, 5, 6, 3}, {0, 2, 7, 2, 0},
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
