/* image.c — the layered image behind pn_image: creation, extra AOV layers, the public
 * accessors (all of which tolerate NULL) and the public read/write entry points, which wrap the
 * internal file functions and copy their errors into the context.
 */
#include "core/file.h"
#include "io/image.h"

#include "core/context.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* Pixel count of an image, or 0 when width * height * 3 floats would not fit in size_t. */
static size_t pn_image_pixel_count(int width, int height) {
    if (width <= 0 || height <= 0) return 0;
    size_t w = (size_t)width, h = (size_t)height;
    if (w > SIZE_MAX / 3 / sizeof(float) / h) return 0;
    return w * h;
}

pn_status pn_image_check_size(const char *name, const char *format, int64_t width, int64_t height,
                              const pn_image_limits *limits, uint64_t pixels_per_byte, pn_err *err) {
    if (width <= 0 || height <= 0)
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid %s file: size %lldx%lld", name, format,
                          (long long)width, (long long)height);
    /* Both sides are below 2^32 in every format, so the product cannot overflow. */
    uint64_t pixels = (uint64_t)width * (uint64_t)height;
    if ((uint64_t)width > UINT32_MAX || (uint64_t)height > UINT32_MAX || pixels > limits->max_pixels)
        return pn_err_set(err, PN_ERROR_BAD_INPUT,
                          "%s: %s image of %lldx%lld pixels is larger than the image pixel limit of %llu pixels", name,
                          format, (long long)width, (long long)height, (unsigned long long)limits->max_pixels);
    if (pixels_per_byte > 0 && pixels / pixels_per_byte > limits->file_size)
        return pn_err_set(err, PN_ERROR_BAD_INPUT,
                          "%s: not a valid %s file: %lldx%lld pixels cannot be stored in %llu bytes", name, format,
                          (long long)width, (long long)height, (unsigned long long)limits->file_size);
    return PN_OK;
}

uint64_t pn_context_image_pixel_limit(pn_context ctx) {
    return ctx && ctx->image_pixel_limit ? ctx->image_pixel_limit : PN_IMAGE_MAX_PIXELS_DEFAULT;
}

void pn_context_set_image_pixel_limit(pn_context ctx, uint64_t max_pixels) {
    if (ctx) ctx->image_pixel_limit = max_pixels;
}

pn_image pn_image_create(int width, int height) {
    size_t pixels = pn_image_pixel_count(width, height);
    if (pixels == 0) return NULL;
    pn_image image = calloc(1, sizeof *image);
    if (!image) return NULL;
    image->width = width;
    image->height = height;
    if (!pn_image_add_layer(image, "", 3)) {
        pn_image_free(image);
        return NULL;
    }
    return image;
}

float *pn_image_add_layer(pn_image image, const char *name, int channels) {
    if (!image || !name || channels < 1 || channels > 4) return NULL;
    size_t pixels = pn_image_pixel_count(image->width, image->height);
    if (pixels == 0) return NULL;

    size_t name_len = strlen(name);
    char *name_copy = malloc(name_len + 1);
    float *data = calloc(pixels * (size_t)channels, sizeof(float));
    pn_image_layer *layers = realloc(image->layers, ((size_t)image->layer_count + 1) * sizeof *layers);
    if (layers) image->layers = layers;
    if (!name_copy || !data || !layers) {
        free(name_copy);
        free(data);
        return NULL;
    }
    memcpy(name_copy, name, name_len + 1);

    pn_image_layer *layer = &image->layers[image->layer_count++];
    layer->name = name_copy;
    layer->channels = channels;
    layer->data = data;
    return data;
}

void pn_image_free(pn_image image) {
    if (!image) return;
    for (int i = 0; i < image->layer_count; i++) {
        free(image->layers[i].name);
        free(image->layers[i].data);
    }
    free(image->layers);
    free(image);
}

int pn_image_width(pn_image image) {
    return image ? image->width : 0;
}

int pn_image_height(pn_image image) {
    return image ? image->height : 0;
}

int pn_image_layer_count(pn_image image) {
    return image ? image->layer_count : 0;
}

/* The layer at `index`, or NULL when the image is NULL or the index is out of range. */
static const pn_image_layer *pn_image_layer_at(pn_image image, int index) {
    if (!image || index < 0 || index >= image->layer_count) return NULL;
    return &image->layers[index];
}

const char *pn_image_layer_name(pn_image image, int layer) {
    const pn_image_layer *l = pn_image_layer_at(image, layer);
    return l ? l->name : "";
}

int pn_image_layer_channels(pn_image image, int layer) {
    const pn_image_layer *l = pn_image_layer_at(image, layer);
    return l ? l->channels : 0;
}

const float *pn_image_layer_data(pn_image image, int layer) {
    const pn_image_layer *l = pn_image_layer_at(image, layer);
    return l ? l->data : NULL;
}

pn_status pn_image_read(pn_context ctx, const char *path, pn_image *out_image) {
    pn_err err;
    pn_err_init(&err);
    if (out_image) *out_image = NULL;
    if (!path || !out_image) {
        pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_image_read: %s is NULL", path ? "out_image" : "path");
        return pn_context_fail_from(ctx, &err);
    }
    pn_status status = pn_image_read_file_limit(path, 0.0f, pn_context_image_pixel_limit(ctx), out_image, &err);
    if (status != PN_OK) {
        /* The file layer always records a message; make sure a bare status is never lost. */
        if (err.status == PN_OK) pn_err_set(&err, status, "%s: cannot read image", path);
        return pn_context_fail_from(ctx, &err);
    }
    return PN_OK;
}

pn_status pn_image_read_layer(pn_context ctx, const char *path, const char *layer, pn_image *out_image) {
    if (out_image) *out_image = NULL;
    if (!ctx || !path || !layer || !out_image) return PN_ERROR_INVALID_ARGUMENT;
    pn_err err;
    pn_err_init(&err);
    uint64_t size = 0;
    FILE *f = pn_file_open_regular(path, PN_INPUT_FILE_MAX_BYTES, &size, &err);
    if (!f) return pn_context_fail(ctx, err.status, "%s: %s", path, err.message);
    pn_image grey = NULL;
    pn_image_limits limits = {size, pn_context_image_pixel_limit(ctx)};
    pn_status st = pn_exr_read_channel(f, path, layer, &limits, &grey, &err);
    fclose(f);
    if (st != PN_OK) return pn_context_fail_from(ctx, &err);
    const size_t n = (size_t)grey->width * (size_t)grey->height;
    float *dst = pn_image_add_layer(grey, layer, 1);
    if (!dst) {
        pn_image_free(grey);
        return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for layer %s", layer);
    }
    const float *rgb = grey->layers[0].data;
    for (size_t i = 0; i < n; i++) dst[i] = rgb[3 * i];
    *out_image = grey;
    return PN_OK;
}

pn_status pn_image_write(pn_context ctx, pn_image image, const char *path, float exposure) {
    pn_err err;
    pn_err_init(&err);
    if (!image || !path) {
        pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_image_write: %s is NULL", image ? "path" : "image");
        return pn_context_fail_from(ctx, &err);
    }
    pn_status status = pn_image_write_file(image, path, exposure, &err);
    if (status != PN_OK) {
        if (err.status == PN_OK) pn_err_set(&err, status, "%s: cannot write image", path);
        return pn_context_fail_from(ctx, &err);
    }
    return PN_OK;
}
