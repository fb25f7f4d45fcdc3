/* image_ops.c — operations on whole images that are not file formats: cropping. */
#include "core/context.h"
#include "io/image.h"

#include <string.h>

pn_status pn_image_crop(pn_context ctx, pn_image image, int x0, int y0, int width, int height, pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !image || !out_image) return PN_ERROR_INVALID_ARGUMENT;
    if (x0 < 0 || y0 < 0 || width <= 0 || height <= 0 || x0 > image->width - width || y0 > image->height - height)
        return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "crop %dx%d at (%d, %d) does not fit in a %dx%d image",
                               width, height, x0, y0, image->width, image->height);
    pn_image out = pn_image_create(width, height);
    if (!out) return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", width, height);
    for (int l = 0; l < image->layer_count; l++) {
        const pn_image_layer *src = &image->layers[l];
        float *dst = l == 0 ? out->layers[0].data : pn_image_add_layer(out, src->name, src->channels);
        if (!dst) {
            pn_image_free(out);
            return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", width, height);
        }
        size_t c = (size_t)src->channels, row = (size_t)width * c;
        for (int y = 0; y < height; y++)
            memcpy(dst + (size_t)y * row, src->data + ((size_t)(y0 + y) * (size_t)image->width + (size_t)x0) * c,
                   row * sizeof *dst);
    }
    *out_image = out;
    return PN_OK;
}
