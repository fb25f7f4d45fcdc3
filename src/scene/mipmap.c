/* mipmap.c — image-texture pyramids and filtered lookups as pbrt-v4 builds and reads them
 * (util/image.cpp GeneratePyramid, util/mipmap.cpp MIPMap::Filter), so that textured surfaces
 * reflect what they reflect in pbrt-v4 (issue 20: staircase-matte).
 *
 * Pyramid: an image whose width or height is not a power of two is first resized up to the next
 * powers of two, separably (x, then y), each output texel a normalised 4-tap windowed sinc
 * (Lanczos, radius 2, tau 2) of the input around its centre (i + 0.5) * old / new, input texels
 * outside the image taken by the texture's wrap mode, results clamped at 0; every further level
 * is the 2x2 box average of the one below (a side of 1 texel stays 1), down to 1x1. All in linear
 * float. Difference: pbrt stores each level back in the source's pixel format (8-bit sRGB for TGA
 * / PNG / JPEG), so its levels are rounded to 8 bits; penumbra keeps floats (a rounding error of
 * at most half an 8-bit sRGB step per texel, no mean bias to first order).
 *
 * Lookup at (s, t) with the screen-space derivatives (ds/dx, dt/dx), (ds/dy, dt/dy):
 * width = 2 max(|ds/dx|, |dt/dx|, |ds/dy|, |dt/dy|), level = levels - 1 + log2(max(width,
 * 1e-8)); at or beyond the top level, the top texel; else with l = max(0, floor(level)):
 * "point" the nearest texel of level l, "bilinear" a bilinear lookup in level l, "trilinear"
 * bilinear in level 0 when l = 0, else the blend of levels l and l + 1 by level - l. "ewa" is
 * read as trilinear (difference, docs/pbrt-v4-differences.md). With zero derivatives (rays
 * without differentials: shadow-ray alpha tests, light paths, secondary hits) every filter reads
 * level 0. */
#include "scene/build.h"

#include "scene/parser_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static bool is_pow2(int n) {
    return n > 0 && (n & (n - 1)) == 0;
}

static int round_up_pow2(int n) {
    int p = 1;
    while (p < n) p <<= 1;
    return p;
}

/* Remaps a texel coordinate into [0, n) by the wrap mode; false for PN_WRAP_BLACK outside. */
static bool wrap_coord(int *x, int n, pn_wrap_mode wrap) {
    if (*x >= 0 && *x < n) return true;
    switch (wrap) {
    case PN_WRAP_BLACK: return false;
    case PN_WRAP_CLAMP: *x = *x < 0 ? 0 : n - 1; return true;
    case PN_WRAP_REPEAT:
    default:
        *x %= n;
        if (*x < 0) *x += n;
        return true;
    }
}

static float sinc(float x) {
    x *= PN_PI;
    return fabsf(x) < 1e-5f ? 1.0f - x * x / 6.0f : sinf(x) / x;
}

static float windowed_sinc(float x, float radius, float tau) {
    return fabsf(x) > radius ? 0.0f : sinc(x) * sinc(x / tau);
}

/* The four input texels and weights of each output texel when n_old texels become n_new. */
typedef struct resample_tap {
    int first;
    float w[4];
} resample_tap;

static resample_tap *resample_taps(int n_old, int n_new) {
    resample_tap *taps = malloc((size_t)n_new * sizeof *taps);
    if (!taps) return NULL;
    const float radius = 2.0f, tau = 2.0f;
    for (int i = 0; i < n_new; i++) {
        float centre = ((float)i + 0.5f) * (float)n_old / (float)n_new;
        taps[i].first = (int)floorf(centre - radius + 0.5f);
        float sum = 0.0f;
        for (int j = 0; j < 4; j++) {
            float pos = (float)(taps[i].first + j) + 0.5f;
            taps[i].w[j] = windowed_sinc(pos - centre, radius, tau);
            sum += taps[i].w[j];
        }
        for (int j = 0; j < 4; j++) taps[i].w[j] /= sum;
    }
    return taps;
}

/* One separable pass: `lines` lines of n_in texels become lines of n_out by the taps; texel k of
 * line l is at index l * line + k * along (in units of RGB texels) of its buffer. */
typedef struct axis_layout {
    size_t in_line, in_along, out_line, out_along;
} axis_layout;

static void resample_axis(const float *in, float *out, int lines, int n_in, int n_out, const resample_tap *taps,
                          axis_layout a, pn_wrap_mode wrap, bool clamp_zero) {
    for (int l = 0; l < lines; l++)
        for (int k = 0; k < n_out; k++) {
            float acc[3] = {0, 0, 0};
            for (int j = 0; j < 4; j++) {
                int src = taps[k].first + j;
                if (!wrap_coord(&src, n_in, wrap)) continue;
                const float *p = in + 3 * ((size_t)l * a.in_line + (size_t)src * a.in_along);
                for (int c = 0; c < 3; c++) acc[c] += taps[k].w[j] * p[c];
            }
            float *q = out + 3 * ((size_t)l * a.out_line + (size_t)k * a.out_along);
            for (int c = 0; c < 3; c++) q[c] = clamp_zero ? fmaxf(0.0f, acc[c]) : acc[c];
        }
}

/* Resizes rgb (w x h) up to (nw x nh) with the taps above, x first (every input row), then y,
 * clamped at 0 after the second pass (as FloatResizeUp); NULL when out of memory. */
static float *resize_up(const float *rgb, int w, int h, int nw, int nh, pn_wrap_mode wrap) {
    resample_tap *tx = resample_taps(w, nw), *ty = resample_taps(h, nh);
    float *xbuf = malloc(3 * (size_t)nw * (size_t)h * sizeof *xbuf);
    float *out = malloc(3 * (size_t)nw * (size_t)nh * sizeof *out);
    if (tx && ty && xbuf && out) {
        resample_axis(rgb, xbuf, h, w, nw, tx, (axis_layout){(size_t)w, 1, (size_t)nw, 1}, wrap, false);
        resample_axis(xbuf, out, nw, h, nh, ty, (axis_layout){1, (size_t)nw, 1, (size_t)nw}, wrap, true);
    } else {
        free(out);
        out = NULL;
    }
    free(tx);
    free(ty);
    free(xbuf);
    return out;
}

void pn_mipmap_free(pn_mipmap *m) {
    if (!m) return;
    for (int i = 0; i < m->levels; i++) free(m->level[i].rgb);
    free(m->level);
    memset(m, 0, sizeof *m);
}

pn_status pn_mipmap_build(const float *rgb, int width, int height, pn_wrap_mode wrap, pn_mipmap *out, pn_err *err) {
    memset(out, 0, sizeof *out);
    int w = width, h = height;
    float *base = NULL;
    if (!is_pow2(w) || !is_pow2(h)) {
        int nw = round_up_pow2(w), nh = round_up_pow2(h);
        base = resize_up(rgb, w, h, nw, nh, wrap);
        w = nw;
        h = nh;
    } else {
        base = malloc(3 * (size_t)w * (size_t)h * sizeof *base);
        if (base) memcpy(base, rgb, 3 * (size_t)w * (size_t)h * sizeof *base);
    }
    if (!base) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a texture pyramid");
    int levels = 1;
    for (int m = w > h ? w : h; m > 1; m >>= 1) levels++;
    out->level = calloc((size_t)levels, sizeof *out->level);
    if (!out->level) {
        free(base);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a texture pyramid");
    }
    out->wrap = wrap;
    out->level[0] = (pn_mip_level){w, h, base};
    out->levels = 1;
    for (int l = 1; l < levels; l++) {
        const pn_mip_level *src = &out->level[l - 1];
        int nw = src->width > 1 ? src->width / 2 : 1, nh = src->height > 1 ? src->height / 2 : 1;
        float *dst = malloc(3 * (size_t)nw * (size_t)nh * sizeof *dst);
        if (!dst) {
            pn_mipmap_free(out);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a texture pyramid");
        }
        /* Neighbours across a side of one texel are the texel itself. */
        int dx = src->width > 1 ? 1 : 0, dy = src->height > 1 ? 1 : 0;
        for (int y = 0; y < nh; y++)
            for (int x = 0; x < nw; x++) {
                size_t a = (size_t)(2 * y) * (size_t)src->width + (size_t)(2 * x);
                size_t b = a + (size_t)dx, c = a + (size_t)dy * (size_t)src->width, d = c + (size_t)dx;
                for (int k = 0; k < 3; k++)
                    dst[3 * ((size_t)y * (size_t)nw + (size_t)x) + (size_t)k] =
                        0.25f * (src->rgb[3 * a + (size_t)k] + src->rgb[3 * b + (size_t)k] +
                                 src->rgb[3 * c + (size_t)k] + src->rgb[3 * d + (size_t)k]);
            }
        out->level[l] = (pn_mip_level){nw, nh, dst};
        out->levels = l + 1;
    }
    return PN_OK;
}

static vec3 level_texel(const pn_mip_level *lv, int x, int y, pn_wrap_mode wrap) {
    if (!wrap_coord(&x, lv->width, wrap) || !wrap_coord(&y, lv->height, wrap)) return v3(0, 0, 0);
    const float *p = lv->rgb + 3 * ((size_t)y * (size_t)lv->width + (size_t)x);
    return v3(p[0], p[1], p[2]);
}

/* (s, t) in texel units of the level, texel centres at integers; false when not finite. */
static bool level_coords(const pn_mip_level *lv, float s, float t, double *x, double *y) {
    *x = (double)s * lv->width - 0.5;
    *y = (double)t * lv->height - 0.5;
    if (!isfinite(*x) || !isfinite(*y)) return false;
    /* Keep the integer coordinates in range of int for huge s, t (repeat wraps them anyway). */
    if (fabs(*x) > 1e8 || fabs(*y) > 1e8) {
        *x = fmod(*x, (double)lv->width);
        *y = fmod(*y, (double)lv->height);
    }
    return true;
}

vec3 pn_mip_level_bilerp(const pn_mip_level *lv, float s, float t, pn_wrap_mode wrap) {
    double x, y;
    if (!level_coords(lv, s, t, &x, &y)) return v3(0, 0, 0);
    double fx0 = floor(x), fy0 = floor(y);
    float dx = (float)(x - fx0), dy = (float)(y - fy0);
    int x0 = (int)fx0, y0 = (int)fy0;
    vec3 a = level_texel(lv, x0, y0, wrap), b = level_texel(lv, x0 + 1, y0, wrap);
    vec3 c = level_texel(lv, x0, y0 + 1, wrap), d = level_texel(lv, x0 + 1, y0 + 1, wrap);
    vec3 top = v3_add(v3_scale(a, 1.0f - dx), v3_scale(b, dx));
    vec3 bottom = v3_add(v3_scale(c, 1.0f - dx), v3_scale(d, dx));
    return v3_add(v3_scale(top, 1.0f - dy), v3_scale(bottom, dy));
}

vec3 pn_mipmap_lookup(const pn_mipmap *m, pn_texture_filter filter, float s, float t, const float dst[4]) {
    float width = 0.0f;
    for (int i = 0; i < 4; i++) width = fmaxf(width, fabsf(dst[i]));
    width *= 2.0f;
    float level = (float)(m->levels - 1) + log2f(fmaxf(width, 1e-8f));
    if (!(level < (float)(m->levels - 1))) return level_texel(&m->level[m->levels - 1], 0, 0, m->wrap);
    int il = level > 0.0f ? (int)floorf(level) : 0;
    const pn_mip_level *lv = &m->level[il];
    switch (filter) {
    case PN_TEXTURE_FILTER_POINT: {
        double x, y;
        if (!level_coords(lv, s, t, &x, &y)) return v3(0, 0, 0);
        return level_texel(lv, (int)round(x), (int)round(y), m->wrap);
    }
    case PN_TEXTURE_FILTER_BILINEAR: return pn_mip_level_bilerp(lv, s, t, m->wrap);
    case PN_TEXTURE_FILTER_TRILINEAR:
    default: {
        if (il == 0) return pn_mip_level_bilerp(lv, s, t, m->wrap);
        float f = level - (float)il;
        vec3 a = pn_mip_level_bilerp(lv, s, t, m->wrap), b = pn_mip_level_bilerp(lv + 1, s, t, m->wrap);
        return v3_add(v3_scale(a, 1.0f - f), v3_scale(b, f));
    }
    }
}

pn_status pn_scene_mipmap(struct pn_scene_s *scene, int image, pn_wrap_mode wrap, int *out_index, pn_err *err) {
    for (int i = 0; i < scene->mipmap_count; i++)
        if (scene->mipmaps[i].image == image && scene->mipmaps[i].wrap == wrap) {
            *out_index = i;
            return PN_OK;
        }
    if (!pn_grow_for_append((void **)&scene->mipmaps, scene->mipmap_count, sizeof *scene->mipmaps))
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a texture pyramid");
    const pn_texture_image *img = &scene->images[image];
    pn_mipmap *m = &scene->mipmaps[scene->mipmap_count];
    pn_status st = pn_mipmap_build(img->rgb, img->width, img->height, wrap, m, err);
    if (st != PN_OK) return st;
    m->image = image;
    *out_index = scene->mipmap_count++;
    return PN_OK;
}
