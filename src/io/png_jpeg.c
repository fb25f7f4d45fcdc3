/* png_jpeg.c — decoding PNG with libpng and JPEG with libjpeg-turbo, and encoding PNG with libpng (Debian libpng-dev,
 * libjpeg-dev), the field's well-kept decoders, instead of stb_image (issue 19, finding 1: stb's
 * Huffman table builder writes out of bounds on a forged JPEG).
 *
 * Both libraries report errors through a callback that must not return; each reader keeps its
 * setjmp/longjmp inside this file, around the library calls only, and every allocation it owns
 * is reachable from a volatile local so that the error path frees it. Samples come out as they
 * are stored (no gAMA/ICC conversion, as stb did), and the gamma rule of image.h turns them into
 * linear values. The header's size is checked against the pixel limit and the file size before
 * any pixel buffer is allocated; a progressive JPEG may have at most PN_JPEG_MAX_SCANS scans
 * (each rescans the whole coefficient buffer: thousands of tiny scans are a CPU bomb).
 */
#include "io/image.h"

#include <jpeglib.h>
#include <png.h>
#include <errno.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>

#define PN_JPEG_MAX_SCANS 256

/* ---------------------------------------------------------------------------------------- */
/* PNG */

typedef struct pn_png_state {
    jmp_buf jump;
    char message[200];
} pn_png_state;

static void pn_png_error(png_structp png, png_const_charp message) {
    pn_png_state *state = png_get_error_ptr(png);
    snprintf(state->message, sizeof state->message, "%s", message ? message : "corrupt data");
    longjmp(state->jump, 1);
}

static void pn_png_warning(png_structp png, png_const_charp message) {
    (void)png;
    (void)message;
}

pn_status pn_png_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                      pn_err *err) {
    *out = NULL;
    pn_png_state state;
    state.message[0] = '\0';
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &state, pn_png_error, pn_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_read_struct(png ? &png : NULL, NULL, NULL);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    }
    /* Owned buffers, volatile so that their values survive the longjmp. */
    unsigned char *volatile pixels = NULL;
    png_bytep *volatile rows = NULL;
    pn_image volatile image = NULL;
    pn_status volatile status = PN_OK;
    if (setjmp(state.jump)) {
        free(pixels);
        free(rows);
        pn_image_free(image);
        png_destroy_read_struct(&png, &info, NULL);
        if (status != PN_OK) return status;
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid PNG file: %s", name, state.message);
    }
    png_init_io(png, file);
    png_read_info(png, info);
    png_uint_32 width = 0, height = 0;
    int depth = 0, color = 0;
    png_get_IHDR(png, info, &width, &height, &depth, &color, NULL, NULL, NULL);
    status = pn_image_check_size(name, "PNG", width, height, limits, PN_IMAGE_MAX_PIXELS_PER_BYTE, err);
    if (status != PN_OK) longjmp(state.jump, 1);

    /* Palette to RGB, sub-byte grey to 8 bits, alpha (and tRNS) dropped, 16-bit in host order. */
    if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (color == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if ((color & PNG_COLOR_MASK_ALPHA) || png_get_valid(png, info, PNG_INFO_tRNS)) png_set_strip_alpha(png);
    if (depth == 16) {
        const uint16_t probe = 1;
        if (*(const unsigned char *)&probe == 1) png_set_swap(png);
    }
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    int comp = png_get_channels(png, info);
    size_t row_bytes = png_get_rowbytes(png, info);
    int kind = png_get_bit_depth(png, info) == 16 ? 16 : 8;
    if (comp < 1 || comp > 4 || row_bytes < (size_t)width * (size_t)comp * (size_t)(kind / 8)) {
        snprintf(state.message, sizeof state.message, "unsupported layout");
        longjmp(state.jump, 1);
    }
    pixels = malloc(row_bytes * height);
    rows = malloc(sizeof *rows * height);
    image = pn_image_create((int)width, (int)height);
    if (!pixels || !rows || !image) {
        status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for %ux%u image", name, (unsigned)width,
                            (unsigned)height);
        longjmp(state.jump, 1);
    }
    for (png_uint_32 y = 0; y < height; y++) rows[y] = pixels + (size_t)y * row_bytes;
    png_read_image(png, rows);
    /* Rows are packed at row_bytes, which equals width * comp * bytes for these transforms. */
    pn_image_fill_rgb(image->layers[0].data, (size_t)width * height, comp, pixels, kind, gamma);
    free(pixels);
    free(rows);
    png_destroy_read_struct(&png, &info, NULL);
    *out = image;
    return PN_OK;
}

pn_status pn_png_encode_rgb8(FILE *file, const char *name, int width, int height, const unsigned char *pixels,
                             pn_err *err) {
    pn_png_state state;
    state.message[0] = '\0';
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &state, pn_png_error, pn_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!png || !info) {
        png_destroy_write_struct(png ? &png : NULL, NULL);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    }
    if (setjmp(state.jump)) {
        png_destroy_write_struct(&png, &info);
        if (ferror(file)) return pn_err_set(err, PN_ERROR_IO, "%s: %s", name, strerror(errno ? errno : EIO));
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: PNG encoding failed: %s", name, state.message);
    }
    png_init_io(png, file);
    png_set_IHDR(png, info, (png_uint_32)width, (png_uint_32)height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_write_info(png, info);
    for (int y = 0; y < height; y++) png_write_row(png, pixels + (size_t)y * (size_t)width * 3);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return PN_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* JPEG */

typedef struct pn_jpeg_state {
    struct jpeg_error_mgr manager; /* first: libjpeg passes a pointer to it */
    struct jpeg_progress_mgr progress;
    jmp_buf jump;
    char message[JMSG_LENGTH_MAX];
} pn_jpeg_state;

static void pn_jpeg_error_exit(j_common_ptr cinfo) {
    pn_jpeg_state *state = (pn_jpeg_state *)(void *)cinfo->err;
    (*cinfo->err->format_message)(cinfo, state->message);
    longjmp(state->jump, 1);
}

static void pn_jpeg_output_message(j_common_ptr cinfo) {
    (void)cinfo; /* warnings (e.g. "premature end of data") are not printed */
}

/* Ends the decoding of a progressive file with too many scans. */
static void pn_jpeg_progress(j_common_ptr cinfo) {
    if (!cinfo->is_decompressor) return;
    j_decompress_ptr d = (j_decompress_ptr)cinfo;
    if (d->input_scan_number > PN_JPEG_MAX_SCANS) {
        pn_jpeg_state *state = (pn_jpeg_state *)(void *)cinfo->err;
        snprintf(state->message, sizeof state->message, "more than %d progressive scans", PN_JPEG_MAX_SCANS);
        longjmp(state->jump, 1);
    }
}

pn_status pn_jpeg_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                       pn_err *err) {
    *out = NULL;
    struct jpeg_decompress_struct cinfo;
    pn_jpeg_state state;
    memset(&cinfo, 0, sizeof cinfo);
    state.message[0] = '\0';
    cinfo.err = jpeg_std_error(&state.manager);
    state.manager.error_exit = pn_jpeg_error_exit;
    state.manager.output_message = pn_jpeg_output_message;
    state.progress.progress_monitor = pn_jpeg_progress;
    unsigned char *volatile pixels = NULL;
    pn_image volatile image = NULL;
    pn_status volatile status = PN_OK;
    if (setjmp(state.jump)) {
        free(pixels);
        pn_image_free(image);
        jpeg_destroy_decompress(&cinfo);
        if (status != PN_OK) return status;
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid JPEG file: %s", name, state.message);
    }
    jpeg_create_decompress(&cinfo);
    cinfo.progress = &state.progress;
    jpeg_stdio_src(&cinfo, file);
    jpeg_read_header(&cinfo, TRUE);
    status = pn_image_check_size(name, "JPEG", cinfo.image_width, cinfo.image_height, limits,
                                 PN_IMAGE_MAX_PIXELS_PER_BYTE, err);
    if (status != PN_OK) longjmp(state.jump, 1);
    if (cinfo.jpeg_color_space == JCS_CMYK || cinfo.jpeg_color_space == JCS_YCCK) {
        snprintf(state.message, sizeof state.message, "CMYK JPEG files are not supported");
        longjmp(state.jump, 1);
    }
    cinfo.out_color_space = cinfo.num_components == 1 ? JCS_GRAYSCALE : JCS_RGB;
    jpeg_start_decompress(&cinfo);
    const int comp = cinfo.output_components;
    const size_t width = cinfo.output_width, height = cinfo.output_height;
    if (comp != 1 && comp != 3) {
        snprintf(state.message, sizeof state.message, "unsupported layout");
        longjmp(state.jump, 1);
    }
    pixels = malloc(width * height * (size_t)comp);
    image = pn_image_create((int)width, (int)height);
    if (!pixels || !image) {
        status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for %zux%zu image", name, width, height);
        longjmp(state.jump, 1);
    }
    while (cinfo.output_scanline < cinfo.output_height) {
        JSAMPROW row = pixels + (size_t)cinfo.output_scanline * width * (size_t)comp;
        jpeg_read_scanlines(&cinfo, &row, 1);
    }
    jpeg_finish_decompress(&cinfo);
    jpeg_destroy_decompress(&cinfo);
    pn_image_fill_rgb(image->layers[0].data, width * height, comp, pixels, 8, gamma);
    free(pixels);
    *out = image;
    return PN_OK;
}
