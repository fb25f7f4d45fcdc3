/* image.h — the image type behind the public pn_image handle, and the file readers/writers.
 *
 * An image is a stack of named layers of equal size; layer 0 is the beauty ("", 3 channels RGB).
 * Pixels are row-major, top row first, channels interleaved. Implemented in io/image.c (layers,
 * public accessors), io/exr.c (OpenEXR C core), io/pfm.c, io/ldr.c (stb_image / stb_image_write)
 * and io/write.c (atomic temporary-file-and-rename writes).
 */
#ifndef PN_IO_IMAGE_H
#define PN_IO_IMAGE_H

#include "core/error.h"
#include "penumbra/penumbra.h"

#include <stdint.h>
#include <stdio.h>

typedef struct pn_image_layer {
    char *name;   /* "" for beauty; AOV names such as "shadow_rays", "normal" */
    int channels; /* 1 or 3 */
    float *data;  /* channels * width * height */
} pn_image_layer;

struct pn_image_s {
    int width, height;
    int layer_count;
    pn_image_layer *layers;
    /* Where the pixels lie in the whole image (a crop render's data window inside its display
     * window, as pbrt-v4 writes crops): origin of pixel (0, 0) and the full size. All zero: the
     * image is the whole picture. The EXR writer and pn_image_read_layers keep these. */
    int origin_x, origin_y, display_width, display_height;
};

/* A new image with a zeroed 3-channel beauty layer; NULL when out of memory or w/h <= 0. */
pn_image pn_image_create(int width, int height);

/* Appends a zeroed layer and returns its pixels (NULL when out of memory). */
float *pn_image_add_layer(pn_image image, const char *name, int channels);

/* The pixel limit of every image reader unless the context sets another
 * (pn_context_set_image_pixel_limit): 16384 x 16384 pixels, 3 GiB as RGB floats. */
#define PN_IMAGE_MAX_PIXELS_DEFAULT ((uint64_t)1 << 28)

/* No format read through stb or libpng stores more pixels per byte of file than this: a 1-bit
 * PNG holds 8 pixels per raw byte and zlib compresses by at most 1032:1 (8 x 1032 = 8256). JPEG
 * needs at least one bit per 8x8 block (512 pixels per byte), RLE TGA 2 bytes per 128 pixels. */
#define PN_IMAGE_MAX_PIXELS_PER_BYTE 8256

/* What a reader may allocate: the file's size and the pixel limit. */
typedef struct pn_image_limits {
    uint64_t file_size;
    uint64_t max_pixels;
} pn_image_limits;

/* Checks a header's width x height before anything is allocated: PN_ERROR_BAD_INPUT when
 * either is not positive, when there are more than limits->max_pixels pixels, or (when
 * pixels_per_byte > 0) more than the file could hold at pixels_per_byte per byte of file. */
pn_status pn_image_check_size(const char *name, const char *format, int64_t width, int64_t height,
                              const pn_image_limits *limits, uint64_t pixels_per_byte, pn_err *err);

/* The pixel limit in force on a context (the default when none was set or ctx is NULL). */
uint64_t pn_context_image_pixel_limit(pn_context ctx);

/* Reads EXR (first RGB(A) or Y layer of any pixel type, scanline or tiled), PFM, PNG, TGA, JPG,
 * BMP, HDR into a one-layer RGB image. 8-bit formats are converted with `gamma`: 0 = the sRGB
 * curve, 1 = linear (v / 255), other = v^gamma. Greyscale is replicated into RGB; alpha is
 * dropped. Errors read "path: message" (PN_ERROR_BAD_INPUT for malformed or unsupported files,
 * PN_ERROR_IO when the file cannot be opened). */
pn_status pn_image_read_file(const char *path, float gamma, pn_image *out, pn_err *err);
/* The same with a pixel limit (0 = PN_IMAGE_MAX_PIXELS_DEFAULT) instead of the default. */
pn_status pn_image_read_file_limit(const char *path, float gamma, uint64_t max_pixels, pn_image *out, pn_err *err);

/* Writes by extension (.exr all layers as 32-bit float; .pfm beauty; .png beauty as 8-bit sRGB
 * after multiplying by 2^exposure and clamping). Writes a temporary file in the same folder and
 * renames it, so a failure leaves no partial file at `path`. */
/* Writes a file atomically: write_to fills a fresh temporary beside path, which is synced and
 * renamed over path; on any failure the temporary is removed and path is untouched. */
typedef pn_status (*pn_write_fn)(void *user, FILE *file, const char *path, pn_err *err);
pn_status pn_write_atomic(const char *path, pn_write_fn write_to, void *user, pn_err *err);
pn_status pn_image_write_file(pn_image image, const char *path, float exposure, pn_err *err);

/* Format back ends, called by io/write.c. Readers get a file opened for reading and positioned
 * at its start; writers get a new, empty file opened for writing (the EXR writer uses pwrite on
 * fileno(file) and leaves the FILE buffer untouched). `name` is the path shown in messages,
 * which always read "name: message". */
pn_status pn_exr_read(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err);
/* pn_exr_read of the one channel `channel` (an AOV layer's, e.g. "illuminance"), as grey. */
pn_status pn_exr_read_channel(FILE *file, const char *name, const char *channel, const pn_image_limits *limits,
                              pn_image *out, pn_err *err);
pn_status pn_pfm_read(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err);
pn_status pn_ldr_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                      pn_err *err);
/* io/png_jpeg.c: PNG through libpng, JPEG through libjpeg-turbo. */
pn_status pn_png_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                      pn_err *err);
pn_status pn_jpeg_read(FILE *file, const char *name, float gamma, const pn_image_limits *limits, pn_image *out,
                       pn_err *err);
/* Writes 8-bit RGB rows (width * 3 bytes each, top first) as a PNG file through libpng. */
pn_status pn_png_encode_rgb8(FILE *file, const char *name, int width, int height, const unsigned char *pixels,
                             pn_err *err);
/* Moves interleaved samples with `comp` channels (1-2 grey(+alpha), 3-4 RGB(+alpha)) of type
 * `kind` (8, 16: integers decoded with the gamma rule; 32: linear floats) into RGB (io/ldr.c). */
void pn_image_fill_rgb(float *rgb, size_t pixels, int comp, const void *data, int kind, float gamma);
pn_status pn_exr_write(pn_image image, FILE *file, const char *name, pn_err *err);
/* Reads every channel of the first flat part as float layers (the writer's naming reversed:
 * R, G, B the beauty; "x.R", "x.G", "x.B" a three-channel layer "x"; any other channel a
 * one-channel layer), with the data window inside the display window in origin_x/y and
 * display_width/height. For `penumbra merge`. Refuses, before allocating, a data window over
 * the limits, or more samples (pixels x channels) than an RGB image at the pixel limit. */
pn_status pn_exr_read_layers(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err);
pn_status pn_pfm_write(pn_image image, FILE *file, const char *name, pn_err *err);
pn_status pn_png_write(pn_image image, float exposure, FILE *file, const char *name, pn_err *err);

#endif
