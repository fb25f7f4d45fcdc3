/* image_merge.c — crop images and their assembly: reading every layer of an EXR with its data
 * window (pn_image_read_layers), and `penumbra merge`'s step that puts crop renders of one image
 * back together (pn_image_merge). Pixels are copied, never resampled or averaged, so parts
 * rendered with the same settings assemble into the bit-identical full image. */
#include "core/file.h"
#include "core/context.h"
#include "io/image.h"

#include <errno.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

pn_status pn_image_read_layers(pn_context ctx, const char *path, pn_image *out_image) {
    pn_err err;
    pn_err_init(&err);
    if (out_image) *out_image = NULL;
    if (!path || !out_image) {
        pn_err_set(&err, PN_ERROR_INVALID_ARGUMENT, "pn_image_read_layers: NULL argument");
        return pn_context_fail_from(ctx, &err);
    }
    uint64_t size = 0;
    FILE *file = pn_file_open_regular(path, PN_INPUT_FILE_MAX_BYTES, &size, &err);
    if (!file) {
        pn_err reason = err;
        pn_err_set(&err, reason.status, "%s: %s", path, reason.message);
        return pn_context_fail_from(ctx, &err);
    }
    struct stat st;
    pn_status status;
    if (fstat(fileno(file), &st) != 0 || !S_ISREG(st.st_mode))
        status = pn_err_set(&err, PN_ERROR_IO, "%s: not a regular file", path);
    else {
        pn_image_limits limits = {size, pn_context_image_pixel_limit(ctx)};
        status = pn_exr_read_layers(file, path, &limits, out_image, &err);
    }
    fclose(file);
    return status == PN_OK ? PN_OK : pn_context_fail_from(ctx, &err);
}

void pn_image_window(pn_image image, int window[4]) {
    if (!image) return;
    bool crop = image->display_width > 0 && image->display_height > 0;
    window[0] = crop ? image->origin_x : 0;
    window[1] = crop ? image->origin_y : 0;
    window[2] = crop ? image->display_width : image->width;
    window[3] = crop ? image->display_height : image->height;
}

/* The layers of b are those of a: same count, names, channels, in the same order. */
static bool same_layers(pn_image a, pn_image b, char *why, size_t size) {
    if (a->layer_count != b->layer_count) {
        snprintf(why, size, "%d layers where the first part has %d", b->layer_count, a->layer_count);
        return false;
    }
    for (int l = 0; l < a->layer_count; l++)
        if (strcmp(a->layers[l].name, b->layers[l].name) != 0 || a->layers[l].channels != b->layers[l].channels) {
            snprintf(why, size, "layer %d is '%s' (%d channels) where the first part has '%s' (%d channels)", l,
                     b->layers[l].name, b->layers[l].channels, a->layers[l].name, a->layers[l].channels);
            return false;
        }
    return true;
}

pn_status pn_image_merge(pn_context ctx, const pn_image *parts, const char *const *names, int count,
                         pn_image *out_image) {
    if (out_image) *out_image = NULL;
    bool given = ctx && parts && names && count >= 1 && out_image;
    for (int i = 0; given && i < count; i++) given = parts[i] && names[i];
    if (!given) return pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_image_merge: no parts, or a NULL part");
    int w0[4];
    pn_image_window(parts[0], w0);
    const int W = w0[2], H = w0[3];
    char why[512];
    for (int i = 1; i < count; i++) {
        int w[4];
        pn_image_window(parts[i], w);
        if (w[2] != W || w[3] != H)
            return pn_context_fail(ctx, PN_ERROR_BAD_INPUT,
                                   "%s: a part of a %dx%d image, but %s is a part of a %dx%d image (display windows "
                                   "differ: parts of different renders?)",
                                   names[i], w[2], w[3], names[0], W, H);
        if (!same_layers(parts[0], parts[i], why, sizeof why))
            return pn_context_fail(ctx, PN_ERROR_BAD_INPUT, "%s: %s (%s): parts of different renders?", names[i], why,
                                   names[0]);
    }
    /* Which part covers each pixel (0: none yet). */
    int *owner = calloc((size_t)W * (size_t)H, sizeof *owner);
    pn_image out = pn_image_create(W, H);
    for (int l = 1; out && l < parts[0]->layer_count; l++)
        if (!pn_image_add_layer(out, parts[0]->layers[l].name, parts[0]->layers[l].channels)) {
            pn_image_free(out);
            out = NULL;
        }
    if (!owner || !out) {
        free(owner);
        pn_image_free(out);
        return pn_context_fail(ctx, PN_ERROR_OUT_OF_MEMORY, "out of memory for a %dx%d image", W, H);
    }
    pn_status st = PN_OK;
    for (int i = 0; i < count && st == PN_OK; i++) {
        pn_image p = parts[i];
        int w[4];
        pn_image_window(p, w);
        for (int y = 0; y < p->height && st == PN_OK; y++)
            for (int x = 0; x < p->width; x++) {
                int *o = &owner[(size_t)(w[1] + y) * (size_t)W + (size_t)(w[0] + x)];
                if (*o) {
                    st = pn_context_fail(ctx, PN_ERROR_BAD_INPUT, "%s overlaps %s at pixel (%d, %d)", names[i],
                                         names[*o - 1], w[0] + x, w[1] + y);
                    break;
                }
                *o = i + 1;
            }
        for (int l = 0; l < p->layer_count && st == PN_OK; l++) {
            size_t c = (size_t)p->layers[l].channels, row = (size_t)p->width * c;
            for (int y = 0; y < p->height; y++)
                memcpy(out->layers[l].data + ((size_t)(w[1] + y) * (size_t)W + (size_t)w[0]) * c,
                       p->layers[l].data + (size_t)y * row, row * sizeof(float));
        }
    }
    size_t missing = 0, first = 0;
    for (size_t i = 0; st == PN_OK && i < (size_t)W * (size_t)H; i++)
        if (!owner[i] && missing++ == 0) first = i;
    if (st == PN_OK && missing)
        st = pn_context_fail(ctx, PN_ERROR_BAD_INPUT,
                             "the parts do not cover the %dx%d image: %zu pixels are in no part, the first at (%zu, "
                             "%zu)",
                             W, H, missing, first % (size_t)W, first / (size_t)W);
    free(owner);
    if (st != PN_OK) {
        pn_image_free(out);
        return st;
    }
    *out_image = out;
    return PN_OK;
}
