/* test_io.c — image files and metrics: EXR/PFM/PNG round trips, EXR files of other pixel types
 * and layouts written here with the OpenEXR C core, atomic writes, truncated and garbage input,
 * closed-form metrics and image comparison, and (when ../shared exists) a reference render. */
#include "harness.h"

#include "core/context.h"
#include "film/metrics.h"
#include "io/image.h"

#include <dirent.h>
#include <errno.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openexr.h>

/* ---------------------------------------------------------------------------------------- */
/* Helpers */

/* A fresh scratch folder under /tmp; remove it with remove_dir. */
static void make_dir(char *buf, size_t size) {
    snprintf(buf, size, "/tmp/pn-test-io-XXXXXX");
    if (!mkdtemp(buf)) {
        perror("mkdtemp");
        exit(1);
    }
}

/* Number of entries in a folder (without "." and ".."), and whether any name holds `needle`. */
static int count_entries(const char *dir, const char *needle, int *found) {
    DIR *d = opendir(dir);
    int n = 0;
    if (found) *found = 0;
    if (!d) return -1;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        n++;
        if (found && needle && strstr(e->d_name, needle)) *found = 1;
    }
    closedir(d);
    return n;
}

static void remove_dir(const char *dir) {
    DIR *d = opendir(dir);
    if (!d) return;
    struct dirent *e;
    char path[1024];
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        unlink(path);
    }
    closedir(d);
    rmdir(dir);
}

static unsigned char *read_bytes(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *buf = malloc(n > 0 ? (size_t)n : 1);
    *size = fread(buf, 1, (size_t)(n > 0 ? n : 0), f);
    fclose(f);
    return buf;
}

static int write_bytes(const char *path, const void *data, size_t size) {
    FILE *f = fopen(path, "wb");
    if (!f) return 0;
    size_t n = size ? fwrite(data, 1, size, f) : 0;
    fclose(f);
    return n == size;
}

/* A deterministic test pattern with negative, tiny, large and fractional values. */
static float pattern(int x, int y, int c, int seed) {
    uint32_t h =
        (uint32_t)x * 73856093u ^ (uint32_t)y * 19349663u ^ (uint32_t)c * 83492791u ^ (uint32_t)seed * 2654435761u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    float v = (float)(h & 0xffffu) / 4096.0f - 2.0f;
    if ((h >> 16) % 7 == 0) v *= 1.0e4f;
    if ((h >> 16) % 11 == 0) v *= 1.0e-6f;
    return v;
}

static pn_image make_test_image(int w, int h, int with_aovs) {
    pn_image img = pn_image_create(w, h);
    if (!img) return NULL;
    float *beauty = img->layers[0].data;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < 3; c++) beauty[((size_t)y * w + x) * 3 + c] = pattern(x, y, c, 1);
    if (with_aovs) {
        float *shadow = pn_image_add_layer(img, "shadow_rays", 1);
        float *normal = pn_image_add_layer(img, "normal", 3);
        float *depth = pn_image_add_layer(img, "depth", 1);
        if (!shadow || !normal || !depth) {
            pn_image_free(img);
            return NULL;
        }
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                size_t p = (size_t)y * w + x;
                shadow[p] = (float)(x * 1000 + y);
                depth[p] = pattern(x, y, 7, 3);
                for (int c = 0; c < 3; c++) normal[p * 3 + c] = pattern(x, y, c, 2);
            }
    }
    return img;
}

static int floats_equal(const float *a, const float *b, size_t n) {
    return memcmp(a, b, n * sizeof(float)) == 0;
}

/* Reads one channel of the first part of a scanline EXR as float, planar, into out (w*h). */
static int read_exr_channel(const char *path, const char *channel, int w, int h, float *out) {
    exr_context_t ex = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    if (exr_start_read(&ex, path, &init) != EXR_ERR_SUCCESS) return 0;
    int ok = 1, lines = 0;
    exr_attr_box2i_t dw;
    exr_get_data_window(ex, 0, &dw);
    if (dw.max.x - dw.min.x + 1 != w || dw.max.y - dw.min.y + 1 != h) ok = 0;
    if (exr_get_scanlines_per_chunk(ex, 0, &lines) != EXR_ERR_SUCCESS) ok = 0;
    exr_decode_pipeline_t dec;
    memset(&dec, 0, sizeof dec);
    int ready = 0, found = 0;
    for (int y = dw.min.y; ok && y <= dw.max.y; y += lines) {
        exr_chunk_info_t ci;
        if (exr_read_scanline_chunk_info(ex, 0, y, &ci) != EXR_ERR_SUCCESS) {
            ok = 0;
            break;
        }
        exr_result_t rv = ready ? exr_decoding_update(ex, 0, &ci, &dec) : exr_decoding_initialize(ex, 0, &ci, &dec);
        ready = 1;
        if (rv != EXR_ERR_SUCCESS) {
            ok = 0;
            break;
        }
        for (int i = 0; i < dec.channel_count; i++) {
            exr_coding_channel_info_t *ch = &dec.channels[i];
            ch->decode_to_ptr = NULL;
            if (strcmp(ch->channel_name, channel) == 0) {
                found = 1;
                ch->decode_to_ptr = (uint8_t *)(out + (size_t)(ci.start_y - dw.min.y) * w);
                ch->user_pixel_stride = 4;
                ch->user_line_stride = 4 * w;
                ch->user_data_type = EXR_PIXEL_FLOAT;
                ch->user_bytes_per_element = 4;
            }
        }
        if (!found) {
            ok = 0;
            break;
        }
        if (exr_decoding_choose_default_routines(ex, 0, &dec) != EXR_ERR_SUCCESS ||
            exr_decoding_run(ex, 0, &dec) != EXR_ERR_SUCCESS)
            ok = 0;
    }
    if (ready) exr_decoding_destroy(ex, &dec);
    exr_finish(&ex);
    return ok && found;
}

/* Writes an EXR with the C core for reader tests: channels named in `names` (sorted), all of
 * pixel type `type`, scanline or tiled (8x8 tiles), with a data window starting at (ox, oy).
 * Sample value: value_of(x, y, channel index). */
static float value_of(int x, int y, int c, exr_pixel_type_t type) {
    if (type == EXR_PIXEL_UINT) return (float)(x + 3 * y + 100 * c);
    return (float)(x + 2 * y) / 8.0f + 0.25f * (float)c; /* exact in half for small images */
}

static uint16_t float_to_half_exact(float f) {
    /* Only for values that are exactly representable and normal or zero. */
    uint32_t bits;
    memcpy(&bits, &f, 4);
    uint32_t sign = (bits >> 16) & 0x8000u;
    int32_t exp = (int32_t)((bits >> 23) & 0xff);
    uint32_t mant = bits & 0x7fffffu;
    if (exp == 0) return (uint16_t)sign;
    return (uint16_t)(sign | (uint32_t)(exp - 127 + 15) << 10 | mant >> 13);
}

/* One part of a test file. */
typedef struct test_part {
    const char *part_name; /* needed when there are several parts */
    int tiled;
    exr_pixel_type_t type;
    const char **names; /* channel names, sorted */
    int nchan;
    int w, h, ox, oy;
    exr_compression_t comp;
} test_part;

/* The planar samples of a part in the file's pixel type. */
static unsigned char *make_planes(const test_part *tp, size_t *bpe) {
    *bpe = tp->type == EXR_PIXEL_HALF ? 2 : 4;
    unsigned char *planes = calloc((size_t)tp->nchan * tp->w * tp->h, *bpe);
    for (int c = 0; c < tp->nchan; c++)
        for (int y = 0; y < tp->h; y++)
            for (int x = 0; x < tp->w; x++) {
                float v = value_of(x, y, c, tp->type);
                unsigned char *dst = planes + (((size_t)c * tp->h + y) * tp->w + x) * *bpe;
                if (tp->type == EXR_PIXEL_HALF) {
                    uint16_t hv = float_to_half_exact(v);
                    memcpy(dst, &hv, 2);
                } else if (tp->type == EXR_PIXEL_UINT) {
                    uint32_t u = (uint32_t)v;
                    memcpy(dst, &u, 4);
                } else {
                    memcpy(dst, &v, 4);
                }
            }
    return planes;
}

static int write_part_chunks(exr_context_t ex, int part, const test_part *tp) {
    size_t bpe;
    unsigned char *planes = make_planes(tp, &bpe);
    exr_encode_pipeline_t enc;
    memset(&enc, 0, sizeof enc);
    int ok = 1, ready = 0;
    int step_y = 8, step_x = tp->tiled ? 8 : tp->w;
    if (!tp->tiled) exr_get_scanlines_per_chunk(ex, part, &step_y);
    for (int ty = 0; ok && ty * step_y < tp->h; ty++) {
        for (int tx = 0; ok && tx * step_x < tp->w; tx++) {
            exr_chunk_info_t ci;
            exr_result_t rv = tp->tiled ? exr_write_tile_chunk_info(ex, part, tx, ty, 0, 0, &ci)
                                        : exr_write_scanline_chunk_info(ex, part, tp->oy + ty * step_y, &ci);
            if (rv == EXR_ERR_SUCCESS)
                rv = ready ? exr_encoding_update(ex, part, &ci, &enc) : exr_encoding_initialize(ex, part, &ci, &enc);
            ready = 1;
            if (rv != EXR_ERR_SUCCESS) {
                ok = 0;
                break;
            }
            for (int i = 0; i < enc.channel_count; i++) {
                int c = 0;
                while (c < tp->nchan && strcmp(tp->names[c], enc.channels[i].channel_name) != 0) c++;
                exr_coding_channel_info_t *ch = &enc.channels[i];
                ch->encode_from_ptr =
                    planes + (((size_t)c * tp->h + (size_t)ty * step_y) * tp->w + (size_t)tx * step_x) * bpe;
                ch->user_pixel_stride = (int32_t)bpe;
                ch->user_line_stride = (int32_t)(bpe * tp->w);
                ch->user_data_type = (uint16_t)tp->type;
                ch->user_bytes_per_element = (int16_t)bpe;
            }
            ok = exr_encoding_choose_default_routines(ex, part, &enc) == EXR_ERR_SUCCESS &&
                 exr_encoding_run(ex, part, &enc) == EXR_ERR_SUCCESS;
        }
    }
    if (ready) exr_encoding_destroy(ex, &enc);
    free(planes);
    return ok;
}

/* Writes an EXR with the C core for reader tests: each part has its own channels (all of one
 * pixel type), scanline or tiled (8x8 tiles), with a data window starting at (ox, oy). */
static int write_test_exr_parts(const char *path, const test_part *parts, int nparts) {
    exr_context_t ex = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    if (exr_start_write(&ex, path, EXR_WRITE_FILE_DIRECTLY, &init) != EXR_ERR_SUCCESS) return 0;
    int ok = 1;
    for (int p = 0; ok && p < nparts; p++) {
        const test_part *tp = &parts[p];
        int part = 0;
        ok = exr_add_part(ex, tp->part_name, tp->tiled ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE, &part) ==
                 EXR_ERR_SUCCESS &&
             part == p;
        exr_attr_box2i_t disp, data;
        memset(&disp, 0, sizeof disp);
        disp.max.x = tp->ox + tp->w - 1;
        disp.max.y = tp->oy + tp->h - 1;
        data = disp;
        data.min.x = tp->ox;
        data.min.y = tp->oy;
        exr_attr_v2f_t center;
        memset(&center, 0, sizeof center);
        ok = ok && exr_initialize_required_attr(ex, part, &disp, &data, 1.0f, &center, 1.0f, EXR_LINEORDER_INCREASING_Y,
                                                tp->comp) == EXR_ERR_SUCCESS;
        if (tp->tiled)
            ok = ok &&
                 exr_set_tile_descriptor(ex, part, 8, 8, EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN) == EXR_ERR_SUCCESS;
        for (int c = 0; ok && c < tp->nchan; c++)
            ok = exr_add_channel(ex, part, tp->names[c], tp->type, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1) ==
                 EXR_ERR_SUCCESS;
    }
    ok = ok && exr_write_header(ex) == EXR_ERR_SUCCESS;
    for (int p = 0; ok && p < nparts; p++) ok = write_part_chunks(ex, p, &parts[p]);
    if (exr_finish(&ex) != EXR_ERR_SUCCESS) ok = 0;
    return ok;
}

static int write_test_exr(const char *path, int tiled, exr_pixel_type_t type, const char **names, int nchan, int w,
                          int h, int ox, int oy, exr_compression_t comp) {
    test_part tp = {NULL, tiled, type, names, nchan, w, h, ox, oy, comp};
    return write_test_exr_parts(path, &tp, 1);
}

/* ---------------------------------------------------------------------------------------- */
/* Tests */

static void test_image_layers(void) {
    CHECK(pn_image_create(0, 5) == NULL);
    CHECK(pn_image_create(5, -1) == NULL);
    pn_image img = pn_image_create(4, 3);
    CHECK(img != NULL);
    if (!img) return;
    CHECK(pn_image_width(img) == 4);
    CHECK(pn_image_height(img) == 3);
    CHECK(pn_image_layer_count(img) == 1);
    CHECK(strcmp(pn_image_layer_name(img, 0), "") == 0);
    CHECK(pn_image_layer_channels(img, 0) == 3);
    const float *beauty = pn_image_layer_data(img, 0);
    CHECK(beauty != NULL && beauty[0] == 0.0f && beauty[35] == 0.0f);
    float *d = pn_image_add_layer(img, "depth", 1);
    CHECK(d != NULL && d[11] == 0.0f);
    CHECK(pn_image_layer_count(img) == 2);
    CHECK(strcmp(pn_image_layer_name(img, 1), "depth") == 0);
    CHECK(pn_image_layer_channels(img, 1) == 1);
    CHECK(pn_image_layer_data(img, 1) == d);
    CHECK(pn_image_layer_data(img, 2) == NULL);
    CHECK(pn_image_layer_channels(img, -1) == 0);
    /* NULL safety of every accessor. */
    CHECK(pn_image_width(NULL) == 0);
    CHECK(pn_image_height(NULL) == 0);
    CHECK(pn_image_layer_count(NULL) == 0);
    CHECK(pn_image_layer_data(NULL, 0) == NULL);
    CHECK(pn_image_layer_channels(NULL, 0) == 0);
    const char *name = pn_image_layer_name(NULL, 0);
    CHECK(name != NULL && name[0] == '\0');
    CHECK(pn_image_add_layer(NULL, "x", 1) == NULL);
    pn_image_free(img);
    pn_image_free(NULL);
}

static void test_exr_round_trip(void) {
    char dir[64], path[128];
    make_dir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/round.exr", dir);
    const int w = 37, h = 23; /* not a multiple of the 16-line ZIP chunk */
    pn_image img = make_test_image(w, h, 1);
    CHECK(img != NULL);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(img, path, 0.0f, &err) == PN_OK);
    CHECK_MSG(err.status == PN_OK, "%s", err.message);

    pn_image back = NULL;
    pn_err_init(&err);
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    CHECK_MSG(back != NULL, "%s", err.message);
    if (back) {
        CHECK(back->width == w && back->height == h && back->layer_count == 1);
        CHECK(floats_equal(back->layers[0].data, img->layers[0].data, (size_t)w * h * 3));
    }
    pn_image_free(back);

    /* AOV layers: check channel names and exact values straight from the file. */
    float *plane = malloc(sizeof(float) * w * h);
    const char *names[] = {"B", "G", "R", "depth", "normal.B", "normal.G", "normal.R", "shadow_rays"};
    exr_context_t ex = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    CHECK(exr_start_read(&ex, path, &init) == EXR_ERR_SUCCESS);
    const exr_attr_chlist_t *list = NULL;
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    if (ex && exr_get_channels(ex, 0, &list) == EXR_ERR_SUCCESS && list) {
        CHECK(list->num_channels == 8);
        for (int i = 0; i < list->num_channels && i < 8; i++) {
            CHECK_MSG(strcmp(list->entries[i].name.str, names[i]) == 0, "channel %d is %s", i,
                      list->entries[i].name.str);
            CHECK(list->entries[i].pixel_type == EXR_PIXEL_FLOAT);
        }
        CHECK(exr_get_compression(ex, 0, &comp) == EXR_ERR_SUCCESS && comp == EXR_COMPRESSION_ZIP);
    }
    exr_finish(&ex);

    struct {
        const char *channel;
        int layer, comp;
    } checks[] = {{"R", 0, 0},        {"B", 0, 2},        {"shadow_rays", 1, 0}, {"normal.R", 2, 0},
                  {"normal.G", 2, 1}, {"normal.B", 2, 2}, {"depth", 3, 0}};
    for (size_t k = 0; k < sizeof checks / sizeof checks[0]; k++) {
        const pn_image_layer *L = &img->layers[checks[k].layer];
        CHECK_MSG(read_exr_channel(path, checks[k].channel, w, h, plane), "%s", checks[k].channel);
        int same = 1;
        for (int p = 0; p < w * h; p++)
            if (memcmp(&plane[p], &L->data[(size_t)p * L->channels + checks[k].comp], 4) != 0) same = 0;
        CHECK_MSG(same, "channel %s differs", checks[k].channel);
    }
    free(plane);

    /* The public wrappers behave the same and report through the context. */
    pn_context ctx = pn_context_new();
    snprintf(path, sizeof path, "%s/public.exr", dir);
    CHECK(pn_image_write(ctx, img, path, 0.0f) == PN_OK);
    back = NULL;
    CHECK(pn_image_read(ctx, path, &back) == PN_OK);
    CHECK(back && floats_equal(back->layers[0].data, img->layers[0].data, (size_t)w * h * 3));
    pn_image_free(back);
    CHECK(strcmp(pn_context_error_message(ctx), "") == 0);
    snprintf(path, sizeof path, "%s/missing.exr", dir);
    back = (pn_image)1;
    CHECK(pn_image_read(ctx, path, &back) == PN_ERROR_IO);
    CHECK(back == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "missing.exr: No such file or directory");
    pn_context_free(ctx);

    pn_image_free(img);
    remove_dir(dir);
}

/* A 64x16 chunk of a real render whose ZIP-compressed size equals its packed size: OpenEXR
 * 3.1's encoder wrote it so that it read back as garbage (see src/io/exr.c). */
static void test_exr_zip_equal_size(void) {
    char dir[64], path[128];
    make_dir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/chunk.exr", dir);
    pn_err err;
    pn_err_init(&err);
    pn_image src = NULL, back = NULL;
    CHECK(pn_image_read_file(PN_SOURCE_DIR "/tests/data/exr_zip_equal_size.pfm", 0.0f, &src, &err) == PN_OK);
    CHECK_MSG(src != NULL, "%s", err.message);
    if (!src) return;
    CHECK(src->width == 64 && src->height == 16);
    CHECK(pn_image_write_file(src, path, 0.0f, &err) == PN_OK);
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    if (back) CHECK(floats_equal(back->layers[0].data, src->layers[0].data, (size_t)64 * 16 * 3));
    pn_image_free(back);
    pn_image_free(src);
    unlink(path);
    rmdir(dir);
}

static void test_exr_other_layouts(void) {
    char dir[64], path[128];
    make_dir(dir, sizeof dir);
    struct {
        const char *file;
        int tiled;
        exr_pixel_type_t type;
        const char *names[4];
        int nchan;
        int ox, oy;
        exr_compression_t comp;
        int grey;
    } cases[] = {
        {"half_scan.exr", 0, EXR_PIXEL_HALF, {"B", "G", "R"}, 3, 0, 0, EXR_COMPRESSION_ZIP, 0},
        {"half_tiled_rgba.exr", 1, EXR_PIXEL_HALF, {"A", "B", "G", "R"}, 4, 3, 2, EXR_COMPRESSION_PIZ, 0},
        {"float_tiled.exr", 1, EXR_PIXEL_FLOAT, {"B", "G", "R"}, 3, 0, 0, EXR_COMPRESSION_NONE, 0},
        {"uint_scan.exr", 0, EXR_PIXEL_UINT, {"B", "G", "R"}, 3, -4, 5, EXR_COMPRESSION_RLE, 0},
        {"half_y.exr", 0, EXR_PIXEL_HALF, {"Y"}, 1, 0, 0, EXR_COMPRESSION_ZIPS, 1},
    };
    const int w = 19, h = 13;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        snprintf(path, sizeof path, "%s/%s", dir, cases[k].file);
        int wrote = write_test_exr(path, cases[k].tiled, cases[k].type, cases[k].names, cases[k].nchan, w, h,
                                   cases[k].ox, cases[k].oy, cases[k].comp);
        CHECK_MSG(wrote, "writing %s", cases[k].file);
        if (!wrote) continue;
        pn_image img = NULL;
        pn_err err;
        pn_err_init(&err);
        CHECK_MSG(pn_image_read_file(path, 0.0f, &img, &err) == PN_OK, "%s: %s", cases[k].file, err.message);
        if (!img) continue;
        CHECK(img->width == w && img->height == h);
        int bad = 0;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                for (int c = 0; c < 3; c++) {
                    /* channel index in the sorted name list: B=0/1, G, R depend on alpha */
                    int src;
                    if (cases[k].grey) {
                        src = 0;
                    } else {
                        const char *want = c == 0 ? "R" : c == 1 ? "G" : "B";
                        src = 0;
                        while (strcmp(cases[k].names[src], want) != 0) src++;
                    }
                    float expect = value_of(x, y, src, cases[k].type);
                    float got = img->layers[0].data[((size_t)y * w + x) * 3 + c];
                    if (got != expect) {
                        if (!bad)
                            fprintf(stderr, "  %s (%d,%d,%d): %g vs %g\n", cases[k].file, x, y, c, (double)got,
                                    (double)expect);
                        bad = 1;
                    }
                }
        CHECK_MSG(!bad, "%s pixels", cases[k].file);
        pn_image_free(img);
    }

    /* Two parts: a depth-only part first, then the colour part, which the reader picks. */
    const char *z[] = {"Z"}, *bgr[] = {"B", "G", "R"};
    test_part two[2] = {{"depth", 0, EXR_PIXEL_FLOAT, z, 1, 5, 4, 0, 0, EXR_COMPRESSION_ZIP},
                        {"rgb", 1, EXR_PIXEL_HALF, bgr, 3, 9, 6, 0, 0, EXR_COMPRESSION_ZIP}};
    snprintf(path, sizeof path, "%s/two_parts.exr", dir);
    CHECK(write_test_exr_parts(path, two, 2));
    {
        pn_image img = NULL;
        pn_err err;
        pn_err_init(&err);
        CHECK_MSG(pn_image_read_file(path, 0.0f, &img, &err) == PN_OK, "%s", err.message);
        if (img) {
            CHECK(img->width == 9 && img->height == 6);
            /* pixel (4, 3): R is channel 2 of B, G, R */
            CHECK(img->layers[0].data[(3 * 9 + 4) * 3 + 0] == value_of(4, 3, 2, EXR_PIXEL_HALF));
            CHECK(img->layers[0].data[(3 * 9 + 4) * 3 + 2] == value_of(4, 3, 0, EXR_PIXEL_HALF));
        }
        pn_image_free(img);
    }

    /* No usable channel: a file with only "Z" and "A". */
    const char *za[] = {"A", "Z"};
    snprintf(path, sizeof path, "%s/za.exr", dir);
    if (write_test_exr(path, 0, EXR_PIXEL_FLOAT, za, 2, 4, 4, 0, 0, EXR_COMPRESSION_NONE)) {
        pn_image img = NULL;
        pn_err err;
        pn_err_init(&err);
        CHECK(pn_image_read_file(path, 0.0f, &img, &err) == PN_ERROR_BAD_INPUT);
        CHECK_STR_CONTAINS(err.message, "no R, G, B or Y channel");
        CHECK(img == NULL);
    }
    remove_dir(dir);
}

static void test_pfm(void) {
    char dir[64], path[128];
    make_dir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/a.PFM", dir); /* extension case does not matter */
    const int w = 7, h = 5;
    pn_image img = make_test_image(w, h, 1);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(img, path, 3.0f, &err) == PN_OK);
    pn_image back = NULL;
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    CHECK_MSG(back != NULL, "%s", err.message);
    if (back) {
        CHECK(back->width == w && back->height == h);
        CHECK(floats_equal(back->layers[0].data, img->layers[0].data, (size_t)w * h * 3));
    }
    pn_image_free(back);

    /* Bottom-to-top storage: the first row in the file is the bottom image row. */
    size_t size = 0;
    unsigned char *bytes = read_bytes(path, &size);
    const char *header = "PF\n7 5\n-1.0\n";
    CHECK(bytes && size == strlen(header) + (size_t)w * h * 12);
    if (bytes && size > strlen(header)) {
        CHECK(memcmp(bytes, header, strlen(header)) == 0);
        float first;
        memcpy(&first, bytes + strlen(header), 4);
        CHECK(first == img->layers[0].data[(size_t)(h - 1) * w * 3]);
    }
    free(bytes);
    pn_image_free(img);

    /* Hand-made big-endian greyscale file with scale 2 (values are multiplied by |scale|). */
    unsigned char grey[64];
    int n = snprintf((char *)grey, sizeof grey, "Pf\n2 2\n2.0\n");
    float vals[4] = {1.0f, 2.0f, 3.0f, -4.5f}; /* file order: bottom row first */
    for (int i = 0; i < 4; i++) {
        uint32_t u;
        memcpy(&u, &vals[i], 4);
        grey[n++] = (unsigned char)(u >> 24);
        grey[n++] = (unsigned char)(u >> 16);
        grey[n++] = (unsigned char)(u >> 8);
        grey[n++] = (unsigned char)u;
    }
    snprintf(path, sizeof path, "%s/grey.pfm", dir);
    CHECK(write_bytes(path, grey, (size_t)n));
    back = NULL;
    pn_err_init(&err);
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    if (back) {
        const float *d = back->layers[0].data;
        /* top row = file row 1 = {3, -4.5}; bottom row = {1, 2}; times 2; grey replicated */
        CHECK(d[0] == 6.0f && d[1] == 6.0f && d[2] == 6.0f);
        CHECK(d[3] == -9.0f && d[5] == -9.0f);
        CHECK(d[6] == 2.0f && d[9] == 4.0f && d[11] == 4.0f);
    }
    pn_image_free(back);
    remove_dir(dir);
}

static float srgb_encode(float v) {
    if (v <= 0.0f) return 0.0f;
    if (v >= 1.0f) return 1.0f;
    return v <= 0.0031308f ? v * 12.92f : 1.055f * powf(v, 1.0f / 2.4f) - 0.055f;
}

static void test_png(void) {
    char dir[64], path[128];
    make_dir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/a.png", dir);
    const int w = 16, h = 9;
    pn_image img = pn_image_create(w, h);
    float *d = img->layers[0].data;
    for (int i = 0; i < w * h * 3; i++) d[i] = (float)((i * 37) % 101) / 100.0f;
    d[0] = 5.0f;  /* clamps to 1 */
    d[1] = -1.0f; /* clamps to 0 */
    d[2] = NAN;   /* becomes 0 */
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(img, path, 0.0f, &err) == PN_OK);
    pn_image back = NULL;
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    CHECK_MSG(back != NULL, "%s", err.message);
    if (back) {
        const float *b = back->layers[0].data;
        CHECK(back->width == w && back->height == h);
        CHECK(b[0] == 1.0f && b[1] == 0.0f && b[2] == 0.0f);
        float worst = 0.0f;
        for (int i = 3; i < w * h * 3; i++) {
            float diff = fabsf(srgb_encode(b[i]) - srgb_encode(d[i]));
            if (diff > worst) worst = diff;
        }
        CHECK_MSG(worst <= 1.0f / 255.0f, "worst sRGB difference %g", (double)worst);
    }
    pn_image_free(back);

    /* Exposure +1 doubles; gamma 1 reads code / 255. */
    for (int i = 0; i < w * h * 3; i++) d[i] = 0.25f;
    CHECK(pn_image_write_file(img, path, 1.0f, &err) == PN_OK);
    back = NULL;
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    if (back) CHECK_NEAR(back->layers[0].data[5], 0.5, 0.01);
    pn_image_free(back);
    back = NULL;
    CHECK(pn_image_read_file(path, 1.0f, &back, &err) == PN_OK);
    if (back) CHECK_NEAR(back->layers[0].data[5], 188.0 / 255.0, 1e-6); /* sRGB(0.5) = 0.7354 */
    pn_image_free(back);
    back = NULL;
    CHECK(pn_image_read_file(path, 2.0f, &back, &err) == PN_OK);
    if (back) CHECK_NEAR(back->layers[0].data[5], pow(188.0 / 255.0, 2.0), 1e-6);
    pn_image_free(back);
    CHECK(err.status == PN_OK);
    pn_image_free(img);
    remove_dir(dir);
}

static void test_atomic_write(void) {
    char dir[64], path[160];
    make_dir(dir, sizeof dir);
    pn_image a = make_test_image(8, 8, 0);
    pn_image b = make_test_image(8, 8, 0);
    b->layers[0].data[0] = 42.0f;

    /* A missing folder: an I/O error and nothing written anywhere. */
    snprintf(path, sizeof path, "%s/no/such/folder/out.exr", dir);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(a, path, 0.0f, &err) == PN_ERROR_IO);
    CHECK_STR_CONTAINS(err.message, "No such file or directory");
    CHECK_STR_CONTAINS(err.message, path);
    CHECK(count_entries(dir, NULL, NULL) == 0);

    /* Unknown extension. */
    snprintf(path, sizeof path, "%s/out.xyz", dir);
    pn_err_init(&err);
    CHECK(pn_image_write_file(a, path, 0.0f, &err) == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(err.message, "unknown image format '.xyz' (use .exr, .pfm or .png)");
    CHECK(count_entries(dir, NULL, NULL) == 0);

    /* Replacing an existing file, in every format. */
    const char *exts[] = {"exr", "pfm", "png"};
    for (int k = 0; k < 3; k++) {
        snprintf(path, sizeof path, "%s/out.%s", dir, exts[k]);
        pn_err_init(&err);
        CHECK(pn_image_write_file(a, path, 0.0f, &err) == PN_OK);
        CHECK(pn_image_write_file(b, path, 0.0f, &err) == PN_OK);
        CHECK_MSG(err.status == PN_OK, "%s", err.message);
        pn_image back = NULL;
        CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
        if (back && k < 2) CHECK(back->layers[0].data[0] == 42.0f);
        if (back && k == 2) CHECK(back->layers[0].data[0] == 1.0f);
        pn_image_free(back);
    }
    int found_tmp = 0;
    CHECK(count_entries(dir, ".tmp-", &found_tmp) == 3);
    CHECK(!found_tmp);

    /* A file name so long that the usual temporary name does not fit. */
    char longname[256];
    memset(longname, 'n', 250);
    memcpy(longname + 250, ".pfm", 5);
    char longpath[512];
    snprintf(longpath, sizeof longpath, "%s/%s", dir, longname);
    pn_err_init(&err);
    CHECK_MSG(pn_image_write_file(a, longpath, 0.0f, &err) == PN_OK, "%s", err.message);
    CHECK(count_entries(dir, "tmp-", &found_tmp) == 4);
    CHECK(!found_tmp);
    unlink(longpath);

    /* A folder where the file should go: the write fails and the folder survives. */
    snprintf(path, sizeof path, "%s/sub.exr", dir);
    CHECK(mkdir(path, 0755) == 0);
    pn_err_init(&err);
    CHECK(pn_image_write_file(a, path, 0.0f, &err) == PN_ERROR_IO);
    CHECK(count_entries(dir, ".tmp-", &found_tmp) == 4);
    CHECK(!found_tmp);
    rmdir(path);

    pn_image_free(a);
    pn_image_free(b);
    remove_dir(dir);
}

/* Writes `file` in a format, then re-reads every truncation of it: all must fail cleanly. */
static void check_truncations(const char *dir, const char *ext, int tail_ok) {
    char good[160], bad[160];
    snprintf(good, sizeof good, "%s/good.%s", dir, ext);
    snprintf(bad, sizeof bad, "%s/bad.%s", dir, ext);
    pn_image img = make_test_image(40, 33, 1);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(img, good, 0.0f, &err) == PN_OK);
    pn_image_free(img);
    size_t size = 0;
    unsigned char *bytes = read_bytes(good, &size);
    CHECK(bytes != NULL && size > 100);
    if (!bytes) return;
    /* Every length below 64 bytes (the headers), then a spread through the data. */
    size_t limit = size - (size_t)tail_ok;
    for (size_t len = 0; len < limit; len += (len < 64 ? 1 : 1 + (limit - 64) / 97)) {
        CHECK(write_bytes(bad, bytes, len));
        pn_image back = NULL;
        pn_err_init(&err);
        pn_status st = pn_image_read_file(bad, 0.0f, &back, &err);
        CHECK_MSG(st == PN_ERROR_BAD_INPUT, "%s truncated to %zu of %zu bytes: status %d (%s)", ext, len, size, (int)st,
                  err.message);
        CHECK(back == NULL);
        if (st == PN_ERROR_BAD_INPUT) CHECK_STR_CONTAINS(err.message, bad);
        pn_image_free(back);
    }
    /* The last byte too. */
    CHECK(write_bytes(bad, bytes, limit - 1));
    pn_image back = NULL;
    CHECK(pn_image_read_file(bad, 0.0f, &back, &err) == PN_ERROR_BAD_INPUT);
    pn_image_free(back);
    free(bytes);
}

static void test_truncated_files(void) {
    char dir[64];
    make_dir(dir, sizeof dir);
    check_truncations(dir, "exr", 0);
    check_truncations(dir, "pfm", 0);
    /* stb_image stops at the IEND chunk type and never reads its CRC; the 12-byte IEND chunk
     * is therefore left alone. */
    check_truncations(dir, "png", 12);

    char path[160];
    snprintf(path, sizeof path, "%s/good.exr", dir);
    pn_image back = NULL;
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_read_file(path, 0.0f, &back, &err) == PN_OK);
    pn_image_free(back);
    remove_dir(dir);
}

static void test_garbage_files(void) {
    char dir[64], path[160];
    make_dir(dir, sizeof dir);
    unsigned char junk[4096];
    uint32_t s = 12345u;
    for (size_t i = 0; i < sizeof junk; i++) {
        s = s * 1664525u + 1013904223u;
        junk[i] = (unsigned char)(s >> 24);
    }
    const char *names[] = {"junk.exr", "junk.pfm", "junk.png", "junk.jpg", "junk", "junk.hdr"};
    for (int k = 0; k < 6; k++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        CHECK(write_bytes(path, junk, sizeof junk));
        pn_image img = NULL;
        pn_err err;
        pn_err_init(&err);
        CHECK_MSG(pn_image_read_file(path, 0.0f, &img, &err) == PN_ERROR_BAD_INPUT, "%s: %s", names[k], err.message);
        CHECK(img == NULL);
    }

    /* Right magic numbers followed by junk, and absurd or broken PFM headers. */
    struct {
        const char *name;
        const char *head;
        size_t head_len;
    } heads[] = {
        {"m.exr", "\x76\x2f\x31\x01", 4},
        {"m2.exr", "\x76\x2f\x31\x01\x02\x00\x00\x00", 8},
        {"huge.pfm", "PF\n100000 100000\n-1.0\n", 23},
        {"neg.pfm", "PF\n-3 4\n-1.0\n", 13},
        {"zero.pfm", "PF\n3 4\n0\n", 9},
        {"text.pfm", "Pf\nabc def\n-1\n", 14},
        {"m.png", "\x89PNG\r\n\x1a\n", 8},
    };
    for (size_t k = 0; k < sizeof heads / sizeof heads[0]; k++) {
        unsigned char buf[600];
        memcpy(buf, heads[k].head, heads[k].head_len);
        memcpy(buf + heads[k].head_len, junk, sizeof buf - heads[k].head_len);
        snprintf(path, sizeof path, "%s/%s", dir, heads[k].name);
        CHECK(write_bytes(path, buf, sizeof buf));
        pn_image img = NULL;
        pn_err err;
        pn_err_init(&err);
        CHECK_MSG(pn_image_read_file(path, 0.0f, &img, &err) == PN_ERROR_BAD_INPUT, "%s: %s", heads[k].name,
                  err.message);
        CHECK(img == NULL);
    }

    /* Flipped bytes inside a valid EXR: any outcome but a crash; failures are bad input. */
    pn_image good = make_test_image(30, 30, 0);
    snprintf(path, sizeof path, "%s/flip.exr", dir);
    pn_err err;
    pn_err_init(&err);
    CHECK(pn_image_write_file(good, path, 0.0f, &err) == PN_OK);
    pn_image_free(good);
    size_t size = 0;
    unsigned char *bytes = read_bytes(path, &size);
    for (size_t pos = 8; bytes && pos < size; pos += 1 + size / 61) {
        unsigned char saved = bytes[pos];
        bytes[pos] ^= 0x5a;
        write_bytes(path, bytes, size);
        bytes[pos] = saved;
        pn_image img = NULL;
        pn_err_init(&err);
        pn_status st = pn_image_read_file(path, 0.0f, &img, &err);
        CHECK_MSG(st == PN_OK || st == PN_ERROR_BAD_INPUT, "flip at %zu: %d %s", pos, (int)st, err.message);
        CHECK((st == PN_OK) == (img != NULL));
        pn_image_free(img);
    }
    free(bytes);

    /* Errors for missing files and folders. */
    snprintf(path, sizeof path, "%s/none.pfm", dir);
    pn_image img = NULL;
    pn_err_init(&err);
    CHECK(pn_image_read_file(path, 0.0f, &img, &err) == PN_ERROR_IO);
    CHECK_STR_CONTAINS(err.message, "none.pfm: No such file or directory");
    pn_err_init(&err);
    CHECK(pn_image_read_file(dir, 0.0f, &img, &err) == PN_ERROR_IO);
    snprintf(path, sizeof path, "%s/empty.png", dir);
    CHECK(write_bytes(path, "", 0));
    pn_err_init(&err);
    CHECK(pn_image_read_file(path, 0.0f, &img, &err) == PN_ERROR_BAD_INPUT);
    CHECK(img == NULL);
    remove_dir(dir);
}

static void test_metrics(void) {
    enum { W = 4, H = 3, N = W * H * 3 };
    float ref[N], img[N];
    for (int i = 0; i < N; i++) {
        ref[i] = 1.0f;
        img[i] = 1.5f;
    }
    pn_image_metrics m;
    CHECK(pn_metrics_compute(ref, img, W, H, 3, &m) == PN_OK);
    CHECK_NEAR(m.rmse, 0.5, 1e-12);
    CHECK_NEAR(m.relmse, 0.25 / 1.01, 1e-12);
    CHECK(m.relmse_epsilon == 0.01);
    CHECK_NEAR(m.rel_l1, 0.5, 1e-12);
    CHECK_NEAR(m.rel_l2, 0.5, 1e-12);
    CHECK_NEAR(m.mae, 0.5, 1e-12);
    CHECK_NEAR(m.mean_luminance_reference, 1.0, 1e-12);
    CHECK_NEAR(m.mean_luminance_image, 1.5, 1e-12);

    /* Black reference: relmse = d^2 / 0.01. Half the samples differ by 0.1. */
    for (int i = 0; i < N; i++) {
        ref[i] = 0.0f;
        img[i] = (i % 2) ? 0.1f : 0.0f;
    }
    CHECK(pn_metrics_compute(ref, img, W, H, 3, &m) == PN_OK);
    const double tenth = (double)0.1f;
    CHECK_NEAR(m.relmse, 0.5 * tenth * tenth / 0.01, 1e-12);
    CHECK_NEAR(m.rmse, sqrt(0.5 * tenth * tenth), 1e-12);
    CHECK(isinf(m.rel_l1) && isinf(m.rel_l2));

    /* Identical images: all errors zero; luminance uses Rec. 709 weights. */
    for (int p = 0; p < W * H; p++) {
        ref[p * 3] = img[p * 3] = 1.0f;
        ref[p * 3 + 1] = img[p * 3 + 1] = 0.0f;
        ref[p * 3 + 2] = img[p * 3 + 2] = 0.0f;
    }
    CHECK(pn_metrics_compute(ref, img, W, H, 3, &m) == PN_OK);
    CHECK(m.rmse == 0.0 && m.relmse == 0.0 && m.rel_l1 == 0.0 && m.rel_l2 == 0.0 && m.mae == 0.0);
    CHECK_NEAR(m.mean_luminance_image, 0.2126, 1e-12);

    /* Non-finite samples are skipped and counted. */
    img[0] = NAN;
    img[4] = INFINITY;
    uint64_t bad = 0;
    CHECK(pn_metrics_compute_ex(ref, img, W, H, 3, &m, &bad) == PN_OK);
    CHECK(bad == 2);
    CHECK(isfinite(m.rmse) && isfinite(m.mean_luminance_image));
    CHECK_NEAR(m.mean_luminance_image, 0.2126, 1e-12); /* over the 10 finite pixels */

    CHECK(pn_metrics_compute(NULL, img, W, H, 3, &m) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(pn_metrics_compute(ref, img, 0, H, 3, &m) == PN_ERROR_INVALID_ARGUMENT);
}

static void test_compare(void) {
    pn_context ctx = pn_context_new();
    pn_image a = pn_image_create(512, 512), b = pn_image_create(256, 256);
    pn_image_metrics m;
    pn_image diff = (pn_image)1;
    CHECK(pn_image_compare(ctx, a, b, &m, &diff) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(diff == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "images differ in size: 512x512 vs 256x256");
    pn_image_free(a);
    pn_image_free(b);
    pn_context_clear_error(ctx);

    a = pn_image_create(3, 2);
    b = pn_image_create(3, 2);
    CHECK(pn_image_add_layer(b, "depth", 1) != NULL); /* AOVs are ignored */
    for (int i = 0; i < 18; i++) {
        a->layers[0].data[i] = 1.0f;
        b->layers[0].data[i] = (i % 3 == 0) ? 1.25f : 1.0f;
    }
    CHECK(pn_image_compare(ctx, a, b, &m, &diff) == PN_OK);
    CHECK(diff != NULL);
    if (diff) {
        CHECK(diff->width == 3 && diff->height == 2 && diff->layer_count == 1);
        CHECK(diff->layers[0].data[0] == 4.0f && diff->layers[0].data[1] == 0.0f);
        CHECK(diff->layers[0].data[15] == 4.0f);
    }
    CHECK_NEAR(m.mae, 0.25 / 3.0, 1e-12);
    CHECK_NEAR(m.rel_l1, 0.25 / 3.0, 1e-12);
    CHECK_NEAR(m.mean_luminance_image, 1.0 + 0.25 * 0.2126, 1e-7);
    pn_image_free(diff);
    CHECK(pn_image_compare(ctx, a, b, &m, NULL) == PN_OK);
    CHECK(pn_image_compare(ctx, NULL, b, &m, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_image_free(a);
    pn_image_free(b);
    pn_context_free(ctx);
}

static void test_shared_reference(void) {
    char path[1024];
    snprintf(path, sizeof path, "%s/reference/cornell-box-matte.exr", PN_SHARED_DIR);
    if (PN_SHARED_DIR[0] == '\0' || access(path, R_OK) != 0) {
        pn_test_skip("no ../shared/reference/cornell-box-matte.exr");
        return;
    }
    pn_image img = NULL;
    pn_err err;
    pn_err_init(&err);
    CHECK_MSG(pn_image_read_file(path, 0.0f, &img, &err) == PN_OK, "%s", err.message);
    if (!img) return;
    CHECK(img->width > 0 && img->height > 0);
    size_t n = (size_t)img->width * img->height * 3, nonfinite = 0;
    double sum = 0.0;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(img->layers[0].data[i]))
            nonfinite++;
        else
            sum += (double)img->layers[0].data[i];
    }
    CHECK(nonfinite == 0);
    CHECK(sum > 0.0);

    /* The PNG beside it has the same size. */
    snprintf(path, sizeof path, "%s/reference/cornell-box-matte.png", PN_SHARED_DIR);
    pn_image png = NULL;
    if (access(path, R_OK) == 0) {
        CHECK_MSG(pn_image_read_file(path, 0.0f, &png, &err) == PN_OK, "%s", err.message);
        if (png) CHECK(png->width == img->width && png->height == img->height);
    }
    pn_image_free(png);
    pn_image_free(img);
}

PN_TESTS(TEST(test_image_layers), TEST(test_exr_round_trip), TEST(test_exr_zip_equal_size),
         TEST(test_exr_other_layouts), TEST(test_pfm), TEST(test_png), TEST(test_atomic_write),
         TEST(test_truncated_files), TEST(test_garbage_files), TEST(test_metrics), TEST(test_compare),
         TEST(test_shared_reference))
