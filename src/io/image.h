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

/* Reads EXR (first RGB(A) or Y layer of any pixel type, scanline or tiled), PFM, PNG, TGA, JPG,
 * BMP, HDR into a one-layer RGB image. 8-bit formats are converted with `gamma`: 0 = the sRGB
 * curve, 1 = linear (v / 255), other = v^gamma. Greyscale is replicated into RGB; alpha is
 * dropped. Errors read "path: message" (PN_ERROR_BAD_INPUT for malformed or unsupported files,
 * PN_ERROR_IO when the file cannot be opened). */
pn_status pn_image_read_file(const char *path, float gamma, pn_image *out, pn_err *err);

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
pn_status pn_exr_read(FILE *file, const char *name, pn_image *out, pn_err *err);
/* pn_exr_read of the one channel `channel` (an AOV layer's, e.g. "illuminance"), as grey. */
pn_status pn_exr_read_channel(FILE *file, const char *name, const char *channel, pn_image *out, pn_err *err);
pn_status pn_pfm_read(FILE *file, const char *name, pn_image *out, pn_err *err);
pn_status pn_ldr_read(FILE *file, const char *name, float gamma, pn_image *out, pn_err *err);
pn_status pn_exr_write(pn_image image, FILE *file, const char *name, pn_err *err);
/* Reads every channel of the first flat part as float layers (the writer's naming reversed:
 * R, G, B the beauty; "x.R", "x.G", "x.B" a three-channel layer "x"; any other channel a
 * one-channel layer), with the data window inside the display window in origin_x/y and
 * display_width/height. For `penumbra merge`. */
pn_status pn_exr_read_layers(FILE *file, const char *name, pn_image *out, pn_err *err);
pn_status pn_pfm_write(pn_image image, FILE *file, const char *name, pn_err *err);
pn_status pn_png_write(pn_image image, float exposure, FILE *file, const char *name, pn_err *err);

#endif
