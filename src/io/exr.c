/* exr.c — OpenEXR reading and writing through the OpenEXR C core (libOpenEXRCore).
 *
 * Reading takes the first flat part (scanline or tiled; level 0 of tiled files) that has colour
 * channels, and
 * decodes its R, G, B channels — or Y, replicated into grey — from any pixel type (HALF, FLOAT,
 * UINT) to float. Writing stores every layer of the image as 32-bit FLOAT channels in one ZIP
 * compressed scanline part: the beauty as R, G, B; a one-channel layer "name" as channel
 * "name"; a three-channel layer as "name.R", "name.G", "name.B".
 *
 * Both directions use custom streams over an already open descriptor (pread / pwrite), so the
 * library never opens files itself, and an error callback that keeps the library's message
 * instead of letting it print to stderr.
 */
#include "io/image.h"

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

/* Refuse headers describing images larger than this before allocating pixels. */
#define PN_EXR_MAX_DIMENSION (1 << 17)
#define PN_EXR_MAX_PIXELS ((int64_t)1 << 29)

/* State shared with the library callbacks through the context's user data. */
typedef struct pn_exr_stream {
    int fd;
    int64_t size;      /* file size for reading, -1 if unknown */
    int io_errno;      /* first errno seen by the read or write callback */
    char message[256]; /* first message reported by the library */
} pn_exr_stream;

/* ---------------------------------------------------------------------------------------- */
/* A workaround for the ZIP encoder of OpenEXR 3.1 (Debian 12 ships 3.1.5) */

/* When zlib's output is exactly as long as the packed chunk, that encoder stores the zlib bytes
 * with a size equal to the uncompressed size; every reader (its own included) takes a chunk of
 * that size for uncompressed data and decodes garbage (upstream issue 2306, fixed in 2026). The
 * format allows storing any chunk uncompressed when compression does not make it smaller, so in
 * that case the packed bytes are stored instead. The library's own compression routine is kept
 * and called first. */
typedef exr_result_t (*pn_exr_compress_fn)(exr_encode_pipeline_t *encode);

typedef struct pn_exr_compress_guard {
    pn_exr_compress_fn inner;
} pn_exr_compress_guard;

static exr_result_t pn_exr_compress_guarded(exr_encode_pipeline_t *encode) {
    const pn_exr_compress_guard *g = encode->encoding_user_data;
    exr_result_t rv = g->inner(encode);
    if (rv == EXR_ERR_SUCCESS && encode->compressed_buffer && encode->packed_buffer &&
        encode->compressed_buffer != encode->packed_buffer && encode->compressed_bytes == encode->packed_bytes &&
        encode->compressed_alloc_size >= encode->packed_bytes)
        memcpy(encode->compressed_buffer, encode->packed_buffer, (size_t)encode->packed_bytes);
    return rv;
}

/* ---------------------------------------------------------------------------------------- */
/* Stream callbacks */

static int64_t pn_exr_read_fn(exr_const_context_t ctxt, void *user, void *buffer, uint64_t size, uint64_t offset,
                              exr_stream_error_func_ptr_t error_cb) {
    (void)ctxt;
    (void)error_cb;
    pn_exr_stream *s = user;
    uint64_t done = 0;
    while (done < size) {
        ssize_t n = pread(s->fd, (char *)buffer + done, (size_t)(size - done), (off_t)(offset + done));
        if (n < 0) {
            if (errno == EINTR) continue;
            if (!s->io_errno) s->io_errno = errno;
            return -1;
        }
        if (n == 0) break; /* end of file: a short read, which the library reports */
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t pn_exr_size_fn(exr_const_context_t ctxt, void *user) {
    (void)ctxt;
    return ((pn_exr_stream *)user)->size;
}

static int64_t pn_exr_write_fn(exr_const_context_t ctxt, void *user, const void *buffer, uint64_t size, uint64_t offset,
                               exr_stream_error_func_ptr_t error_cb) {
    (void)ctxt;
    (void)error_cb;
    pn_exr_stream *s = user;
    uint64_t done = 0;
    while (done < size) {
        ssize_t n = pwrite(s->fd, (const char *)buffer + done, (size_t)(size - done), (off_t)(offset + done));
        if (n < 0) {
            if (errno == EINTR) continue;
            if (!s->io_errno) s->io_errno = errno;
            return -1;
        }
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

/* Read contexts never hold their lock while reporting, so asking for the user data here is
 * safe; the first message is kept. */
static void pn_exr_read_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    (void)code;
    void *user = NULL;
    if (!ctxt || !msg || exr_get_user_data(ctxt, &user) != EXR_ERR_SUCCESS || !user) return;
    pn_exr_stream *s = user;
    if (s->message[0] == '\0') snprintf(s->message, sizeof s->message, "%s", msg);
}

/* Write contexts report errors while holding their lock, so this handler must not call back
 * into the library; it only keeps the messages off stderr. The result codes carry the cause. */
static void pn_exr_quiet_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    (void)ctxt;
    (void)code;
    (void)msg;
}

/* The best description of a failure: the library's own message, else the code's text. */
static const char *pn_exr_reason(const pn_exr_stream *s, exr_result_t rv) {
    if (s->message[0]) return s->message;
    const char *text = exr_get_default_error_message(rv);
    return text ? text : "unknown error";
}

/* ---------------------------------------------------------------------------------------- */
/* Reading */

/* Index of the channel called `name` in the list, or -1. */
static int pn_exr_find_channel(const exr_attr_chlist_t *list, const char *name) {
    for (int i = 0; i < list->num_channels; i++) {
        if (list->entries[i].name.str && strcmp(list->entries[i].name.str, name) == 0) return i;
    }
    return -1;
}

/* Reading state: where each wanted channel goes in the interleaved RGB output. */
typedef struct pn_exr_reader {
    exr_context_t ex;
    int part; /* the part being read */
    pn_exr_stream *stream;
    const char *name;
    pn_err *err;
    float *rgb;
    int64_t min_x, min_y;
    int width, height;
    const char *source[3]; /* channel feeding R, G, B (NULL = none) */
    exr_decode_pipeline_t decode;
    int decode_ready;
    const char *channel; /* pn_exr_read_channel: the one channel wanted (read as grey), else NULL */
    /* pn_exr_read_layers: one float plane per channel of `list` (NULL: the RGB path above). */
    float **planes;
    const exr_attr_chlist_t *list;
} pn_exr_reader;

static pn_status pn_exr_fail(pn_exr_reader *r, exr_result_t rv, const char *what) {
    if (r->stream->io_errno) {
        return pn_err_set(r->err, PN_ERROR_IO, "%s: %s", r->name, strerror(r->stream->io_errno));
    }
    if (rv == EXR_ERR_OUT_OF_MEMORY) {
        return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory while %s", r->name, what);
    }
    return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: not a valid EXR file: %s (%s)", r->name,
                      pn_exr_reason(r->stream, rv), what);
}

/* Decodes one chunk whose top-left pixel is (x0, y0) in data-window coordinates. */
static pn_status pn_exr_decode_chunk(pn_exr_reader *r, const exr_chunk_info_t *cinfo, int64_t x0, int64_t y0) {
    int64_t ox = x0 - r->min_x, oy = y0 - r->min_y;
    if (cinfo->width <= 0 || cinfo->height <= 0 || ox < 0 || oy < 0 || ox + cinfo->width > r->width ||
        oy + cinfo->height > r->height) {
        return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: not a valid EXR file: chunk outside the data window",
                          r->name);
    }
    exr_result_t rv = r->decode_ready ? exr_decoding_update(r->ex, r->part, cinfo, &r->decode)
                                      : exr_decoding_initialize(r->ex, r->part, cinfo, &r->decode);
    if (rv != EXR_ERR_SUCCESS) return pn_exr_fail(r, rv, "preparing to decode");
    r->decode_ready = 1;

    /* The RGB path only: the layer path has no interleaved buffer (r->rgb is NULL, and an offset
     * applied to NULL is undefined, which clang's UBSan reports for every file). */
    float *base = r->planes ? NULL : r->rgb + ((size_t)oy * (size_t)r->width + (size_t)ox) * 3;
    for (int i = 0; i < r->decode.channel_count; i++) {
        exr_coding_channel_info_t *ch = &r->decode.channels[i];
        ch->decode_to_ptr = NULL;
        int plane = r->planes && ch->channel_name ? pn_exr_find_channel(r->list, ch->channel_name) : -1;
        if (plane >= 0) {
            ch->decode_to_ptr = (uint8_t *)(r->planes[plane] + (size_t)oy * (size_t)r->width + (size_t)ox);
            ch->user_pixel_stride = (int32_t)sizeof(float);
            ch->user_line_stride = (int32_t)((size_t)r->width * sizeof(float));
            ch->user_data_type = (uint16_t)EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
            continue;
        }
        for (int c = 0; c < 3 && !r->planes; c++) {
            if (r->source[c] && ch->channel_name && strcmp(ch->channel_name, r->source[c]) == 0) {
                ch->decode_to_ptr = (uint8_t *)(base + c);
                ch->user_pixel_stride = (int32_t)(3 * sizeof(float));
                ch->user_line_stride = (int32_t)((size_t)r->width * 3 * sizeof(float));
                ch->user_data_type = (uint16_t)EXR_PIXEL_FLOAT;
                ch->user_bytes_per_element = (int16_t)sizeof(float);
                break;
            }
        }
    }
    rv = exr_decoding_choose_default_routines(r->ex, r->part, &r->decode);
    if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(r->ex, r->part, &r->decode);
    if (rv != EXR_ERR_SUCCESS) return pn_exr_fail(r, rv, "decoding pixels");
    return PN_OK;
}

static pn_status pn_exr_read_pixels(pn_exr_reader *r, exr_storage_t storage) {
    exr_result_t rv;
    if (storage == EXR_STORAGE_SCANLINE) {
        int32_t lines = 0;
        rv = exr_get_scanlines_per_chunk(r->ex, r->part, &lines);
        if (rv != EXR_ERR_SUCCESS || lines <= 0) return pn_exr_fail(r, rv, "reading chunk size");
        for (int64_t y = r->min_y; y < r->min_y + r->height; y += lines) {
            exr_chunk_info_t cinfo;
            rv = exr_read_scanline_chunk_info(r->ex, r->part, (int)y, &cinfo);
            if (rv != EXR_ERR_SUCCESS) return pn_exr_fail(r, rv, "locating scanlines");
            pn_status st = pn_exr_decode_chunk(r, &cinfo, r->min_x, cinfo.start_y);
            if (st != PN_OK) return st;
        }
        return PN_OK;
    }

    uint32_t tile_w = 0, tile_h = 0;
    exr_tile_level_mode_t level_mode;
    exr_tile_round_mode_t round_mode;
    rv = exr_get_tile_descriptor(r->ex, r->part, &tile_w, &tile_h, &level_mode, &round_mode);
    if (rv != EXR_ERR_SUCCESS || tile_w == 0 || tile_h == 0) {
        return pn_exr_fail(r, rv, "reading the tile description");
    }
    int64_t tiles_x = ((int64_t)r->width + tile_w - 1) / tile_w;
    int64_t tiles_y = ((int64_t)r->height + tile_h - 1) / tile_h;
    for (int64_t ty = 0; ty < tiles_y; ty++) {
        for (int64_t tx = 0; tx < tiles_x; tx++) {
            exr_chunk_info_t cinfo;
            rv = exr_read_tile_chunk_info(r->ex, r->part, (int)tx, (int)ty, 0, 0, &cinfo);
            if (rv != EXR_ERR_SUCCESS) return pn_exr_fail(r, rv, "locating tiles");
            pn_status st = pn_exr_decode_chunk(r, &cinfo, r->min_x + tx * tile_w, r->min_y + ty * tile_h);
            if (st != PN_OK) return st;
        }
    }
    return PN_OK;
}

/* Picks R, G, B (or Y as grey) from the channel list; fills r->source. */
static pn_status pn_exr_choose_channels(pn_exr_reader *r, const exr_attr_chlist_t *list, int *grey) {
    static const char *const rgb_names[3] = {"R", "G", "B"};
    int found = 0;
    *grey = 0;
    if (r->channel) { /* one named channel (an AOV layer), as grey */
        int i = pn_exr_find_channel(list, r->channel);
        if (i < 0)
            return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: EXR file has no channel '%s'", r->name, r->channel);
        r->source[0] = list->entries[i].name.str;
        r->source[1] = r->source[2] = NULL;
        *grey = 1;
        found = -1;
    }
    for (int c = 0; c < 3 && found >= 0; c++) {
        int i = pn_exr_find_channel(list, rgb_names[c]);
        r->source[c] = i >= 0 ? list->entries[i].name.str : NULL;
        found += i >= 0;
    }
    if (found == 0) {
        int i = pn_exr_find_channel(list, "Y");
        if (i < 0 && list->num_channels == 1) i = 0; /* a lone channel of any name is grey */
        if (i < 0) {
            return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: EXR file has no R, G, B or Y channel", r->name);
        }
        r->source[0] = list->entries[i].name.str;
        *grey = 1;
    }
    for (int c = 0; c < 3; c++) {
        if (!r->source[c]) continue;
        const exr_attr_chlist_entry_t *e = &list->entries[pn_exr_find_channel(list, r->source[c])];
        if (e->x_sampling != 1 || e->y_sampling != 1) {
            return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: EXR channel '%s' is subsampled, which is not supported",
                              r->name, r->source[c]);
        }
        if (e->pixel_type != EXR_PIXEL_HALF && e->pixel_type != EXR_PIXEL_FLOAT && e->pixel_type != EXR_PIXEL_UINT) {
            return pn_err_set(r->err, PN_ERROR_BAD_INPUT,
                              "%s: not a valid EXR file: channel '%s' has unknown pixel type", r->name, r->source[c]);
        }
    }
    return PN_OK;
}

/* Starts reading `file` through the OpenEXR C core: the stream over its descriptor (and size, for
 * regular files), the reader state, and the header. stream and r must outlive the read. */
static exr_result_t exr_begin_read(FILE *file, const char *name, pn_exr_stream *stream, pn_exr_reader *r, pn_err *err) {
    memset(stream, 0, sizeof *stream);
    stream->fd = fileno(file);
    struct stat st;
    stream->size = (fstat(stream->fd, &st) == 0 && S_ISREG(st.st_mode)) ? (int64_t)st.st_size : -1;
    memset(r, 0, sizeof *r);
    r->stream = stream;
    r->name = name;
    r->err = err;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = pn_exr_read_error;
    init.user_data = stream;
    init.read_fn = pn_exr_read_fn;
    init.size_fn = pn_exr_size_fn;
    init.flags |= EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    return exr_start_read(&r->ex, name, &init);
}

static pn_status exr_read(FILE *file, const char *name, const char *channel, const pn_image_limits *limits,
                          pn_image *out, pn_err *err);

/* The data window (w x h pixels of part r->part) against the limits, before any pixel is
 * allocated: the pixel limit, and the file's size (every chunk has an 8-byte entry in the offset
 * table, so a header cannot claim more chunks than the file has room for). */
static pn_status pn_exr_check_window(pn_exr_reader *r, int64_t w, int64_t h, const pn_image_limits *limits) {
    pn_status status = pn_image_check_size(r->name, "EXR", w, h, limits, 0, r->err);
    if (status != PN_OK) return status;
    int32_t chunks = 0;
    exr_result_t rv = exr_get_chunk_count(r->ex, r->part, &chunks);
    if (rv != EXR_ERR_SUCCESS) return pn_exr_fail(r, rv, "counting chunks");
    if ((uint64_t)chunks * 8u > limits->file_size)
        return pn_err_set(r->err, PN_ERROR_BAD_INPUT,
                          "%s: not a valid EXR file: %lldx%lld pixels in %d chunks cannot be stored in %llu bytes",
                          r->name, (long long)w, (long long)h, (int)chunks, (unsigned long long)limits->file_size);
    return PN_OK;
}

pn_status pn_exr_read(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err) {
    return exr_read(file, name, NULL, limits, out, err);
}

pn_status pn_exr_read_channel(FILE *file, const char *name, const char *channel, const pn_image_limits *limits,
                              pn_image *out, pn_err *err) {
    return exr_read(file, name, channel, limits, out, err);
}

static pn_status exr_read(FILE *file, const char *name, const char *channel, const pn_image_limits *limits,
                          pn_image *out, pn_err *err) {
    *out = NULL;
    pn_exr_stream stream;
    pn_exr_reader r;
    exr_result_t rv = exr_begin_read(file, name, &stream, &r, err);
    r.channel = channel;
    if (rv != EXR_ERR_SUCCESS) {
        pn_status status = pn_exr_fail(&r, rv, "reading the header");
        if (r.ex) exr_finish(&r.ex);
        return status;
    }

    pn_status status = PN_OK;
    int parts = 0;
    exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *list = NULL;
    int grey = 0;
    pn_image image = NULL;

    rv = exr_get_count(r.ex, &parts);
    if (rv != EXR_ERR_SUCCESS || parts < 1) status = pn_exr_fail(&r, rv, "counting parts");
    if (status == PN_OK) {
        /* The first flat part with R, G, B or Y channels; part 0 when none has them. */
        r.part = 0;
        for (int p = 0; p < parts; p++) {
            const exr_attr_chlist_t *l = NULL;
            exr_storage_t kind;
            if (exr_get_storage(r.ex, p, &kind) != EXR_ERR_SUCCESS ||
                (kind != EXR_STORAGE_SCANLINE && kind != EXR_STORAGE_TILED) ||
                exr_get_channels(r.ex, p, &l) != EXR_ERR_SUCCESS || !l) {
                continue;
            }
            if (pn_exr_find_channel(l, "R") >= 0 || pn_exr_find_channel(l, "G") >= 0 ||
                pn_exr_find_channel(l, "B") >= 0 || pn_exr_find_channel(l, "Y") >= 0) {
                r.part = p;
                break;
            }
        }
        rv = exr_get_storage(r.ex, r.part, &storage);
        if (rv != EXR_ERR_SUCCESS) {
            status = pn_exr_fail(&r, rv, "reading the storage type");
        } else if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
            status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: deep EXR images are not supported", name);
        }
    }
    if (status == PN_OK) {
        rv = exr_get_data_window(r.ex, r.part, &dw);
        if (rv != EXR_ERR_SUCCESS) status = pn_exr_fail(&r, rv, "reading the data window");
    }
    if (status == PN_OK) {
        int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
        if (w <= 0 || h <= 0 || w > PN_EXR_MAX_DIMENSION || h > PN_EXR_MAX_DIMENSION || w * h > PN_EXR_MAX_PIXELS) {
            status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: not a valid EXR file: unsupported data window %lldx%lld",
                                name, (long long)w, (long long)h);
        } else if ((status = pn_exr_check_window(&r, w, h, limits)) == PN_OK) {
            r.width = (int)w;
            r.height = (int)h;
            r.min_x = dw.min.x;
            r.min_y = dw.min.y;
        }
    }
    if (status == PN_OK) {
        rv = exr_get_channels(r.ex, r.part, &list);
        if (rv != EXR_ERR_SUCCESS || !list) status = pn_exr_fail(&r, rv, "reading the channels");
    }
    if (status == PN_OK) status = pn_exr_choose_channels(&r, list, &grey);
    if (status == PN_OK) {
        image = pn_image_create(r.width, r.height);
        if (!image) {
            status =
                pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory for %dx%d image", name, r.width, r.height);
        } else {
            r.rgb = image->layers[0].data;
        }
    }
    if (status == PN_OK) status = pn_exr_read_pixels(&r, storage);

    if (r.decode_ready) exr_decoding_destroy(r.ex, &r.decode);
    exr_finish(&r.ex);

    if (status != PN_OK) {
        pn_image_free(image);
        return status;
    }
    if (grey) {
        float *p = r.rgb;
        size_t pixels = (size_t)r.width * (size_t)r.height;
        for (size_t i = 0; i < pixels; i++) p[i * 3 + 1] = p[i * 3 + 2] = p[i * 3];
    }
    *out = image;
    return PN_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Writing */

/* One output channel: its EXR name and where its samples live. */
typedef struct pn_exr_out_channel {
    char *name;
    const float *data; /* first sample of the channel in the layer */
    int stride;        /* floats between neighbouring pixels (the layer's channel count) */
} pn_exr_out_channel;

static void pn_exr_free_channels(pn_exr_out_channel *chans, int count) {
    if (!chans) return;
    for (int i = 0; i < count; i++) free(chans[i].name);
    free(chans);
}

/* Lists the channels of every layer; names follow the layer rules in the file comment. */
static pn_status pn_exr_list_channels(pn_image image, const char *name, pn_exr_out_channel **out, int *out_count,
                                      pn_err *err) {
    static const char *const suffix[3] = {"R", "G", "B"};
    int total = 0;
    for (int l = 0; l < image->layer_count; l++) total += image->layers[l].channels;
    pn_exr_out_channel *chans = calloc((size_t)total, sizeof *chans);
    if (!chans) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);

    int n = 0;
    for (int l = 0; l < image->layer_count; l++) {
        const pn_image_layer *layer = &image->layers[l];
        const char *lname = layer->name ? layer->name : "";
        if (layer->channels != 1 && layer->channels != 3) {
            pn_exr_free_channels(chans, n);
            return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT,
                              "%s: layer '%s' has %d channels (EXR output takes 1 or 3)", name, lname, layer->channels);
        }
        if (lname[0] == '\0' && (l != 0 || layer->channels != 3)) {
            pn_exr_free_channels(chans, n);
            return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: layer %d has no name", name, l);
        }
        for (int c = 0; c < layer->channels; c++) {
            size_t size = strlen(lname) + 4;
            char *cname = malloc(size);
            if (!cname) {
                pn_exr_free_channels(chans, n);
                return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
            }
            if (lname[0] == '\0') {
                snprintf(cname, size, "%s", suffix[c]);
            } else if (layer->channels == 1) {
                snprintf(cname, size, "%s", lname);
            } else {
                snprintf(cname, size, "%s.%s", lname, suffix[c]);
            }
            chans[n].name = cname;
            chans[n].data = layer->data + c;
            chans[n].stride = layer->channels;
            n++;
        }
    }
    /* The library rejects duplicates too, but a clear message names the culprit. */
    for (int i = 0; i < n; i++) {
        for (int j = i + 1; j < n; j++) {
            if (strcmp(chans[i].name, chans[j].name) == 0) {
                pn_status st = pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: two layers produce the EXR channel '%s'",
                                          name, chans[i].name);
                pn_exr_free_channels(chans, n);
                return st;
            }
        }
    }
    *out = chans;
    *out_count = n;
    return PN_OK;
}

static pn_status pn_exr_write_fail(const pn_exr_stream *s, exr_result_t rv, const char *name, const char *what,
                                   pn_err *err) {
    if (s->io_errno) return pn_err_set(err, PN_ERROR_IO, "%s: %s", name, strerror(s->io_errno));
    if (rv == EXR_ERR_OUT_OF_MEMORY) {
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory while %s", name, what);
    }
    return pn_err_set(err, PN_ERROR_IO, "%s: EXR writing failed while %s: %s", name, what, pn_exr_reason(s, rv));
}

/* Sets the data and display windows of a crop (image->display_width > 0) after the simple
 * header, whose windows are both (0, 0)-(width-1, height-1); returns the data window's first
 * scanline. Keeps *rv at success for whole images, so their files are unchanged. */
static int pn_exr_set_windows(exr_context_t ex, int part, pn_image image, exr_result_t *rv) {
    if (*rv != EXR_ERR_SUCCESS || image->display_width <= 0 || image->display_height <= 0) return 0;
    exr_attr_box2i_t data, display;
    data.min.x = image->origin_x;
    data.min.y = image->origin_y;
    data.max.x = image->origin_x + image->width - 1;
    data.max.y = image->origin_y + image->height - 1;
    display.min.x = display.min.y = 0;
    display.max.x = image->display_width - 1;
    display.max.y = image->display_height - 1;
    *rv = exr_set_display_window(ex, part, &display);
    if (*rv == EXR_ERR_SUCCESS) *rv = exr_set_data_window(ex, part, &data);
    return image->origin_y;
}

pn_status pn_exr_write(pn_image image, FILE *file, const char *name, pn_err *err) {
    pn_exr_out_channel *chans = NULL;
    int count = 0;
    pn_status status = pn_exr_list_channels(image, name, &chans, &count, err);
    if (status != PN_OK) return status;

    pn_exr_stream stream;
    memset(&stream, 0, sizeof stream);
    stream.fd = fileno(file);
    stream.size = -1;

    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = pn_exr_quiet_error;
    init.user_data = &stream;
    init.write_fn = pn_exr_write_fn;

    exr_context_t ex = NULL;
    int part = 0;
    const int width = image->width, height = image->height;
    exr_result_t rv = exr_start_write(&ex, name, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv != EXR_ERR_SUCCESS) {
        status = pn_exr_write_fail(&stream, rv, name, "starting", err);
        goto done;
    }
    rv = exr_add_part(ex, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS) {
        rv = exr_initialize_required_attr_simple(ex, part, width, height, EXR_COMPRESSION_ZIP);
    }
    /* A crop: the data window is the crop inside the whole image's display window. */
    const int oy = pn_exr_set_windows(ex, part, image, &rv);
    if (rv != EXR_ERR_SUCCESS) {
        status = pn_exr_write_fail(&stream, rv, name, "setting up the header", err);
        goto done;
    }
    for (int i = 0; i < count; i++) {
        if (strlen(chans[i].name) > 31) {
            exr_set_longname_support(ex, 1);
            break;
        }
    }
    for (int i = 0; i < count; i++) {
        rv = exr_add_channel(ex, part, chans[i].name, EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
        if (rv != EXR_ERR_SUCCESS) {
            status = pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "%s: cannot add EXR channel '%s': %s", name,
                                chans[i].name, pn_exr_reason(&stream, rv));
            goto done;
        }
    }
    rv = exr_write_header(ex);
    if (rv != EXR_ERR_SUCCESS) {
        status = pn_exr_write_fail(&stream, rv, name, "writing the header", err);
        goto done;
    }

    int32_t lines = 0;
    rv = exr_get_scanlines_per_chunk(ex, part, &lines);
    if (rv != EXR_ERR_SUCCESS || lines <= 0) {
        status = pn_exr_write_fail(&stream, rv, name, "querying the chunk size", err);
        goto done;
    }

    exr_encode_pipeline_t encode;
    memset(&encode, 0, sizeof encode);
    pn_exr_compress_guard guard = {NULL};
    int encode_ready = 0;
    for (int y = 0; y < height && status == PN_OK; y += lines) {
        exr_chunk_info_t cinfo;
        rv = exr_write_scanline_chunk_info(ex, part, oy + y, &cinfo);
        if (rv == EXR_ERR_SUCCESS) {
            rv = encode_ready ? exr_encoding_update(ex, part, &cinfo, &encode)
                              : exr_encoding_initialize(ex, part, &cinfo, &encode);
        }
        if (rv != EXR_ERR_SUCCESS) {
            status = pn_exr_write_fail(&stream, rv, name, "preparing scanlines", err);
            break;
        }
        encode_ready = 1;
        for (int i = 0; i < encode.channel_count; i++) {
            exr_coding_channel_info_t *ch = &encode.channels[i];
            const pn_exr_out_channel *src = NULL;
            for (int k = 0; k < count; k++) {
                if (ch->channel_name && strcmp(ch->channel_name, chans[k].name) == 0) {
                    src = &chans[k];
                    break;
                }
            }
            if (!src) {
                status = pn_err_set(err, PN_ERROR_INTERNAL, "%s: EXR channel '%s' has no source", name,
                                    ch->channel_name ? ch->channel_name : "?");
                break;
            }
            ch->encode_from_ptr = (const uint8_t *)(src->data + (size_t)y * (size_t)width * (size_t)src->stride);
            ch->user_pixel_stride = (int32_t)((size_t)src->stride * sizeof(float));
            ch->user_line_stride = (int32_t)((size_t)src->stride * sizeof(float) * (size_t)width);
            ch->user_data_type = (uint16_t)EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
        }
        if (status != PN_OK) break;
        rv = exr_encoding_choose_default_routines(ex, part, &encode);
        if (rv == EXR_ERR_SUCCESS && encode.compress_fn) {
            guard.inner = encode.compress_fn;
            encode.compress_fn = pn_exr_compress_guarded;
            encode.encoding_user_data = &guard;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(ex, part, &encode);
        if (rv != EXR_ERR_SUCCESS) {
            status = pn_exr_write_fail(&stream, rv, name, "compressing scanlines", err);
        }
    }
    if (encode_ready) exr_encoding_destroy(ex, &encode);

done:
    if (ex) {
        /* exr_finish writes the chunk offset table, so its result matters. */
        rv = exr_finish(&ex);
        if (status == PN_OK && (rv != EXR_ERR_SUCCESS || stream.io_errno)) {
            status = pn_exr_write_fail(&stream, rv, name, "finishing the file", err);
        }
    }
    pn_exr_free_channels(chans, count);
    return status;
}

/* ---------------------------------------------------------------------------------------- */
/* Reading every layer, with its windows (`penumbra merge`) */

/* The layer a channel belongs to: "" for R, G, B; "x" for "x.R"/"x.G"/"x.B" (component in
 * *component, 0..2); otherwise the channel itself (component -1). Writes the layer name. */
static void pn_exr_channel_layer(const char *channel, char *layer, size_t size, int *component) {
    static const char *const suffix[3] = {"R", "G", "B"};
    size_t n = strlen(channel);
    *component = -1;
    for (int c = 0; c < 3; c++) {
        if (strcmp(channel, suffix[c]) == 0) {
            *component = c;
            snprintf(layer, size, "%s", "");
            return;
        }
        if (n > 2 && channel[n - 2] == '.' && strcmp(channel + n - 1, suffix[c]) == 0) {
            *component = c;
            snprintf(layer, size, "%.*s", (int)(n - 2), channel);
            return;
        }
    }
    snprintf(layer, size, "%s", channel);
}

/* Builds the layers of *out from the decoded planes: the beauty first, then the other layers in
 * the file's (sorted) channel order; an RGB triple with a missing member is three 1-channel
 * layers. */
static pn_status pn_exr_planes_to_layers(pn_exr_reader *r, pn_image image) {
    const exr_attr_chlist_t *list = r->list;
    size_t pixels = (size_t)r->width * (size_t)r->height;
    char *used = calloc((size_t)list->num_channels, 1);
    if (!used) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->name);
    pn_status st = PN_OK;
    for (int pass = 0; pass < 2 && st == PN_OK; pass++) {
        for (int i = 0; i < list->num_channels && st == PN_OK; i++) {
            if (used[i]) continue;
            char layer[256];
            int comp;
            pn_exr_channel_layer(list->entries[i].name.str, layer, sizeof layer, &comp);
            if ((pass == 0) != (layer[0] == '\0' && comp >= 0)) continue;
            int members[3] = {-1, -1, -1};
            if (comp >= 0) {
                for (int c = 0; c < 3; c++) {
                    char want[300];
                    snprintf(want, sizeof want, "%s%s%s", layer, layer[0] ? "." : "",
                             c == 0   ? "R"
                             : c == 1 ? "G"
                                      : "B");
                    members[c] = pn_exr_find_channel(list, want);
                }
            }
            int triple = members[0] >= 0 && members[1] >= 0 && members[2] >= 0;
            float *dst;
            if (triple && layer[0] == '\0') {
                dst = image->layers[0].data;
            } else {
                dst = pn_image_add_layer(image, triple ? layer : list->entries[i].name.str, triple ? 3 : 1);
                if (!dst) st = pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->name);
            }
            if (st != PN_OK) break;
            if (triple) {
                for (int c = 0; c < 3; c++) {
                    used[members[c]] = 1;
                    for (size_t p = 0; p < pixels; p++) dst[p * 3 + (size_t)c] = r->planes[members[c]][p];
                }
            } else {
                used[i] = 1;
                memcpy(dst, r->planes[i], pixels * sizeof *dst);
            }
        }
    }
    free(used);
    return st;
}

pn_status pn_exr_read_layers(FILE *file, const char *name, const pn_image_limits *limits, pn_image *out, pn_err *err) {
    *out = NULL;
    pn_exr_stream stream;
    pn_exr_reader r;
    exr_result_t rv = exr_begin_read(file, name, &stream, &r, err);
    pn_status status = rv == EXR_ERR_SUCCESS ? PN_OK : pn_exr_fail(&r, rv, "reading the header");
    exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
    exr_attr_box2i_t dw, disp;
    pn_image image = NULL;
    if (status == PN_OK) {
        rv = exr_get_storage(r.ex, 0, &storage);
        if (rv != EXR_ERR_SUCCESS)
            status = pn_exr_fail(&r, rv, "reading the storage type");
        else if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED)
            status = pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: deep EXR images are not supported", name);
    }
    if (status == PN_OK && ((rv = exr_get_data_window(r.ex, 0, &dw)) != EXR_ERR_SUCCESS ||
                            (rv = exr_get_display_window(r.ex, 0, &disp)) != EXR_ERR_SUCCESS))
        status = pn_exr_fail(&r, rv, "reading the windows");
    if (status == PN_OK) {
        int64_t w = (int64_t)dw.max.x - dw.min.x + 1, h = (int64_t)dw.max.y - dw.min.y + 1;
        int64_t fw = (int64_t)disp.max.x + 1, fh = (int64_t)disp.max.y + 1;
        if (w <= 0 || h <= 0 || w > PN_EXR_MAX_DIMENSION || h > PN_EXR_MAX_DIMENSION || w * h > PN_EXR_MAX_PIXELS ||
            disp.min.x != 0 || disp.min.y != 0 || fw > PN_EXR_MAX_DIMENSION || fh > PN_EXR_MAX_DIMENSION ||
            dw.min.x < 0 || dw.min.y < 0 || dw.max.x >= fw || dw.max.y >= fh) {
            status = pn_err_set(err, PN_ERROR_BAD_INPUT,
                                "%s: unsupported windows: data (%d, %d)-(%d, %d) must lie inside a display window "
                                "starting at (0, 0), here (%d, %d)-(%d, %d)",
                                name, dw.min.x, dw.min.y, dw.max.x, dw.max.y, disp.min.x, disp.min.y, disp.max.x,
                                disp.max.y);
        } else if ((status = pn_exr_check_window(&r, w, h, limits)) == PN_OK) {
            r.width = (int)w;
            r.height = (int)h;
            r.min_x = dw.min.x;
            r.min_y = dw.min.y;
        }
    }
    if (status == PN_OK && ((rv = exr_get_channels(r.ex, 0, &r.list)) != EXR_ERR_SUCCESS || !r.list))
        status = pn_exr_fail(&r, rv, "reading the channels");
    size_t pixels = (size_t)r.width * (size_t)r.height;
    /* Every channel is a plane of floats (and again in the layers): the samples are bounded by
     * those of an RGB image at the pixel limit, whatever the number of channels a header lists. */
    if (status == PN_OK && (uint64_t)pixels * (uint64_t)r.list->num_channels > 3u * limits->max_pixels)
        status = pn_err_set(err, PN_ERROR_BAD_INPUT,
                            "%s: EXR image of %dx%d pixels with %d channels is larger than the image pixel limit "
                            "of %llu pixels with 3 channels",
                            name, r.width, r.height, r.list->num_channels, (unsigned long long)limits->max_pixels);
    if (status == PN_OK) {
        for (int i = 0; i < r.list->num_channels && status == PN_OK; i++)
            if (r.list->entries[i].x_sampling != 1 || r.list->entries[i].y_sampling != 1)
                status =
                    pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: EXR channel '%s' is subsampled, which is not supported",
                               name, r.list->entries[i].name.str);
        r.planes = status == PN_OK ? calloc((size_t)r.list->num_channels, sizeof *r.planes) : NULL;
        image = status == PN_OK ? pn_image_create(r.width, r.height) : NULL;
        if (status == PN_OK && (!r.planes || !image))
            status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
        for (int i = 0; status == PN_OK && i < r.list->num_channels; i++)
            if (!(r.planes[i] = calloc(pixels, sizeof(float))))
                status = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", name);
    }
    if (status == PN_OK) status = pn_exr_read_pixels(&r, storage);
    if (status == PN_OK) status = pn_exr_planes_to_layers(&r, image);
    if (r.planes)
        for (int i = 0; i < r.list->num_channels; i++) free(r.planes[i]);
    free(r.planes);
    if (r.decode_ready) exr_decoding_destroy(r.ex, &r.decode);
    if (r.ex) exr_finish(&r.ex);
    if (status != PN_OK) {
        pn_image_free(image);
        return status;
    }
    if (r.min_x != 0 || r.min_y != 0 || disp.max.x + 1 != r.width || disp.max.y + 1 != r.height) {
        image->origin_x = (int)r.min_x;
        image->origin_y = (int)r.min_y;
        image->display_width = disp.max.x + 1;
        image->display_height = disp.max.y + 1;
    }
    *out = image;
    return PN_OK;
}
