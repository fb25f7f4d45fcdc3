/* ldr.c — the 8-bit and Radiance formats: PNG and JPEG handed to png_jpeg.c (libpng,
 * libjpeg-turbo), the rest (TGA, BMP, HDR, PSD) read by stb_image, and PNG writing (the pixels
 * are encoded here, the file by libpng in png_jpeg.c: stb_image_write's encoder did not survive
 * an allocation failure, found by test_alloc_failures).
 *
 * This is the one file that compiles the stb_image implementation. Radiance
 * HDR files come back linear as they are stored; 8- and 16-bit files are converted to linear
 * with the `gamma` rule of image.h (0 = sRGB curve, 1 = v / max, other = (v / max)^gamma).
 * Greyscale is replicated into RGB and alpha is dropped. PNG output is the beauty layer scaled by
 * 2^exposure, sRGB-encoded, clamped to [0, 1] and rounded to 8 bits.
 */
#include "io/image.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wdouble-promotion"
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wmissing-prototypes"
#pragma GCC diagnostic ignored "-Wstrict-prototypes"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wunused-but-set-variable"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wtype-limits"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#define STB_IMAGE_IMPLEMENTATION
#define STBI_NO_GIF
#define STBI_NO_PIC
#define STBI_NO_PNM
#define STBI_NO_PNG  /* libpng (png_jpeg.c) */
#define STBI_NO_JPEG /* libjpeg-turbo (png_jpeg.c) */
#include "stb_image.h"
#pragma GCC diagnostic pop

/* The sRGB transfer curve and its inverse, on values in [0, 1]. */
static float pn_srgb_to_linear(float v) {
    return v <= 0.04045f ? v / 12.92f : powf((v + 0.055f) / 1.055f, 2.4f);
}

static float pn_linear_to_srgb(float v) {
    return v <= 0.0031308f ? v * 12.92f : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
}

/* Converts an integer sample in [0, 1] (already normalised) with the image.h gamma rule. */
static float pn_decode_sample(float v, float gamma) {
    if (gamma == 0.0f) return pn_srgb_to_linear(v);
    if (gamma == 1.0f) return v;
    return powf(v, gamma);
}

/* A short name for the file type, judged from its first bytes, for error messages. */
static const char *pn_ldr_kind(FILE *file) {
    unsigned char b[8] = {0};
    long pos = ftell(file);
    size_t n = fread(b, 1, sizeof b, file);
    if (pos >= 0) fseek(file, pos, SEEK_SET);
    if (n >= 4 && b[0] == 0x89 && b[1] == 'P' && b[2] == 'N' && b[3] == 'G') return "PNG";
    if (n >= 2 && b[0] == 0xff && b[1] == 0xd8) return "JPEG";
    if (n >= 2 && b[0] == 'B' && b[1] == 'M') return "BMP";
    if (n >= 2 && b[0] == '#' && b[1] == '?') return "Radiance HDR";
    return NULL;
}

/* Moves interleaved samples with `comp` channels into the RGB beauty layer: 1 or 2 channels
 * are grey (plus alpha), 3 or 4 are RGB (plus alpha). `kind` is the sample type: 8 or 16-bit
 * integers (converted with `gamma`) or 32 for linear floats. */
void pn_image_fill_rgb(float *rgb, size_t pixels, int comp, const void *data, int kind, float gamma) {
    /* 8-bit files use a table of all 256 values. */
    float table[256];
    if (kind == 8) {
        for (int i = 0; i < 256; i++) table[i] = pn_decode_sample((float)i / 255.0f, gamma);
    }
    for (size_t p = 0; p < pixels; p++) {
        for (int c = 0; c < 3; c++) {
            size_t src = p * (size_t)comp + (size_t)(comp >= 3 ? c : 0);
            float v;
            if (kind == 8) {
                v = table[((const unsigned char *)data)[src]];
            } else if (kind == 16) {
                v = pn_decode_sample((float)((const uint16_t *)data)[src] / 65535.0f, gamma);
            } else {
                v = ((const float *)data)[src];
            }
            rgb[p * 3 + (size_t)c] = v;
        }
    }
}

/* Radiance HDR run-length scanlines, walked before stb decodes them: stb's decoder loops forever
 * on a zero count, which it also reads at the end of a truncated file (found by fuzz_stb,
 * corpus/stb/regress-19-hdr-zero-count.hdr). Mirrors stb's reading: header lines up to an empty
 * one, the resolution line, then per scanline 2, 2, width (16 bits) and four channels of counts
 * (above 128: a run of count - 128 of one byte; else count literal bytes). Returns 0 when a count
 * is 0 or the file ends inside a scanline; 1 otherwise (stb reports the other errors itself). */
static int pn_hdr_runs_terminate(FILE *file, int width, int height) {
    if (width < 8 || width >= 32768) return 1; /* stb reads such files flat */
    int c, first = -1, lines_done = 0;         /* first: the current line's first byte (-1: none yet) */
    /* The header ends at an empty line — for stb, whose line buffer is a C string, also a line
     * that starts with a NUL byte (found by fuzz_stb: regress-19-hdr-nul-line.hdr) — and the
     * resolution line follows. */
    while (lines_done < 2 && (c = getc(file)) != EOF) {
        if (first < 0) first = c;
        if (c == '\n') {
            if (lines_done == 1 || first == '\n' || first == '\0') lines_done++;
            first = -1;
        }
    }
    for (int y = 0; y < height; y++) {
        int c1 = getc(file), c2 = getc(file), hi = getc(file), lo = getc(file);
        if (c1 != 2 || c2 != 2 || hi == EOF || (hi & 0x80)) return 1; /* flat from here on */
        if (lo == EOF) return 0;
        if (((hi << 8) | lo) != width) return 1;
        for (int k = 0; k < 4; k++) {
            for (int x = 0; x < width;) {
                int count = getc(file);
                if (count == EOF || count == 0) return 0;
                if (count > 128) {
                    if (getc(file) == EOF) return 0;
                    count -= 128;
                } else {
                    for (int i = 0; i < count; i++)
                        if (getc(file) == EOF) return 0;
                }
                x += count;
            }
        }
    }
    return 1;
}

pn_status pn_ldr_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                      pn_err *err) {
    *out = NULL;
    const char *kind_name = pn_ldr_kind(file);
    /* PNG and JPEG go to their own libraries (png_jpeg.c); stb_image keeps the formats that have
     * no packaged decoder: TGA, BMP, Radiance HDR, PSD. */
    if (kind_name && strcmp(kind_name, "PNG") == 0) return pn_png_read(file, name, gamma, limits, out, err);
    if (kind_name && strcmp(kind_name, "JPEG") == 0) return pn_jpeg_read(file, name, gamma, limits, out, err);
    int width = 0, height = 0, comp = 0, kind;
    void *data;
    /* The header's size against the limit and the file's size before stb allocates. */
    if (stbi_info_from_file(file, &width, &height, &comp)) {
        pn_status status = pn_image_check_size(name, kind_name ? kind_name : "image", width, height, limits,
                                               PN_IMAGE_MAX_PIXELS_PER_BYTE, err);
        if (status != PN_OK) return status;
    }
    if (stbi_is_hdr_from_file(file)) {
        int runs_ok = pn_hdr_runs_terminate(file, width, height);
        if (fseek(file, 0, SEEK_SET) != 0 || !runs_ok)
            return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid Radiance HDR file: %s", name,
                              runs_ok ? "cannot seek" : "empty or truncated run-length scanline");
        kind = 32;
        data = stbi_loadf_from_file(file, &width, &height, &comp, 0);
    } else if (stbi_is_16_bit_from_file(file)) {
        kind = 16;
        data = stbi_load_from_file_16(file, &width, &height, &comp, 0);
    } else {
        kind = 8;
        data = stbi_load_from_file(file, &width, &height, &comp, 0);
    }
    if (!data) {
        const char *reason = stbi_failure_reason();
        if (!reason || !reason[0]) reason = "corrupt or truncated data";
        if (kind_name) {
            return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid %s file: %s", name, kind_name, reason);
        }
        return pn_err_set(err, PN_ERROR_BAD_INPUT,
                          "%s: not a supported image file (%s; use EXR, PFM, PNG, JPEG, TGA, BMP "
                          "or HDR)",
                          name, reason);
    }
    if (width <= 0 || height <= 0 || comp < 1 || comp > 4) {
        stbi_image_free(data);
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid image file: bad layout", name);
    }
    pn_image image = pn_image_create(width, height);
    if (!image) {
        stbi_image_free(data);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for %dx%d image", name, width, height);
    }
    pn_image_fill_rgb(image->layers[0].data, (size_t)width * (size_t)height, comp, data, kind, gamma);
    stbi_image_free(data);
    *out = image;
    return PN_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* PNG writing */

/* One linear value to an 8-bit sRGB code; NaN becomes 0. */
static unsigned char pn_encode_8bit(float v) {
    if (!(v > 0.0f)) return 0;
    if (v >= 1.0f) return 255;
    float s = pn_linear_to_srgb(v);
    int code = (int)(s * 255.0f + 0.5f);
    return (unsigned char)(code < 0 ? 0 : code > 255 ? 255 : code);
}

pn_status pn_png_write(pn_image image, float exposure, FILE *file, const char *name, pn_err *err) {
    const int width = image->width, height = image->height;
    size_t count = (size_t)width * (size_t)height * 3;
    unsigned char *pixels = malloc(count);
    if (!pixels) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);

    const float scale = exp2f(exposure);
    const float *rgb = image->layers[0].data;
    for (size_t i = 0; i < count; i++) pixels[i] = pn_encode_8bit(rgb[i] * scale);

    pn_status status = pn_png_encode_rgb8(file, name, width, height, pixels, err);
    free(pixels);
    return status;
}
