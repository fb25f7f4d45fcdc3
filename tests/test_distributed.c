/* test_distributed.c — images that split, merge and resume (docs/distributed.md), in one
 * process: crop renders merged into the full image bit for bit (every layer, through EXR files
 * with their data windows), --piece parts, tiled renders equal to the plain render (contour's
 * bands, illumcut's tiles in one process as in parts), the merge's refusals, and the checkpoint:
 * a cancelled render resumed, a torn last record dropped, corrupt and mismatched files refused. */
#include "harness.h"

#include <penumbra/penumbra.h>

#include <errno.h>
#include <stdbool.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define DEMO PN_SOURCE_DIR "/scenes/demo/demo.pbrt"
#define W 48
#define H 32

static char tmpdir[256];

static const char *tmp_path(const char *name) {
    static char buf[4][512];
    static int k;
    k = (k + 1) % 4;
    if (!tmpdir[0]) {
        snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_distributed.XXXXXX");
        if (!mkdtemp(tmpdir)) tmpdir[0] = '\0';
        pn_test_remove_at_end(tmpdir);
    }
    snprintf(buf[k], sizeof buf[k], "%s/%s", tmpdir, name);
    return buf[k];
}

static void quiet_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    (void)level;
    (void)message;
}

static pn_context new_ctx(void) {
    pn_context ctx = pn_context_new();
    if (ctx) pn_context_set_log(ctx, quiet_log, NULL);
    return ctx;
}

static pn_scene load_demo(pn_context ctx) {
    pn_scene scene = NULL;
    if (pn_scene_load(ctx, DEMO, &scene) != PN_OK) return NULL;
    return scene;
}

typedef struct job {
    pn_integrator_kind integrator;
    const float *crop;
    const char *opts[8]; /* name, value pairs, NULL-terminated */
    uint64_t seed;
    double cancel_at; /* > 0: cancel once progress passes this */
    pn_context ctx;
} job;

static void cancel_progress(void *user, double fraction) {
    job *j = user;
    if (fraction >= j->cancel_at) pn_render_cancel(j->ctx);
}

static pn_status render(pn_scene scene, job *j, pn_image *out, pn_stats stats) {
    pn_options opts = pn_options_new();
    pn_render_settings s;
    memset(&s, 0, sizeof s);
    s.integrator = j->integrator;
    s.width = W;
    s.height = H;
    s.threads = 2;
    s.seed = j->seed;
    s.spp = j->integrator == PN_INTEGRATOR_IAS ? 0 : 2;
    s.aovs = PN_AOV_COMMON;
    if (j->crop) {
        s.has_crop = 1;
        memcpy(s.crop, j->crop, sizeof s.crop);
    }
    /* The VPL integrators with few VPLs, so that each render takes a fraction of a second. */
    if (j->integrator == PN_INTEGRATOR_LIGHTCUTS || j->integrator == PN_INTEGRATOR_ILLUMCUT)
        pn_options_set(j->ctx, opts, "vpls", "500");
    for (int i = 0; j->opts[i]; i += 2) pn_options_set(j->ctx, opts, j->opts[i], j->opts[i + 1]);
    s.options = opts;
    if (j->cancel_at > 0) {
        s.progress = cancel_progress;
        s.progress_user = j;
    }
    pn_status st = pn_render(j->ctx, scene, &s, out, stats);
    pn_options_free(opts);
    return st;
}

/* Every layer of a and b holds the same bits. */
static bool same_image(pn_image a, pn_image b) {
    if (!a || !b || pn_image_width(a) != pn_image_width(b) || pn_image_height(a) != pn_image_height(b) ||
        pn_image_layer_count(a) != pn_image_layer_count(b))
        return false;
    size_t px = (size_t)pn_image_width(a) * (size_t)pn_image_height(a);
    for (int l = 0; l < pn_image_layer_count(a); l++) {
        if (strcmp(pn_image_layer_name(a, l), pn_image_layer_name(b, l)) != 0 ||
            pn_image_layer_channels(a, l) != pn_image_layer_channels(b, l))
            return false;
        if (memcmp(pn_image_layer_data(a, l), pn_image_layer_data(b, l),
                   px * (size_t)pn_image_layer_channels(a, l) * sizeof(float)) != 0)
            return false;
    }
    return true;
}

static pn_image plain(pn_scene scene, pn_context ctx, pn_integrator_kind kind) {
    job j = {kind, NULL, {NULL}, 0, 0, ctx};
    pn_image img = NULL;
    CHECK(render(scene, &j, &img, NULL) == PN_OK);
    return img;
}

/* Four crops of the window, written as EXRs with their data windows, read back and merged: the
 * full render, every layer; the merged file is byte for byte the full render's. */
static void test_crops_merge_to_full(void) {
    pn_context ctx = new_ctx();
    pn_scene scene = load_demo(ctx);
    CHECK(scene != NULL);
    if (!scene) return;
    const pn_integrator_kind kinds[] = {PN_INTEGRATOR_REFERENCE, PN_INTEGRATOR_LIGHTCUTS};
    const float crops[4][4] = {{0, 0.3f, 0, 0.55f}, {0.3f, 1, 0, 0.55f}, {0, 0.7f, 0.55f, 1}, {0.7f, 1, 0.55f, 1}};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        pn_image full = plain(scene, ctx, kinds[k]);
        CHECK(pn_image_write(ctx, full, tmp_path("full.exr"), 0) == PN_OK);
        pn_image parts[4] = {NULL};
        const char *names[4];
        char pathbuf[4][600];
        for (int i = 0; i < 4; i++) {
            job j = {kinds[k], crops[i], {NULL}, 0, 0, ctx};
            pn_image img = NULL;
            CHECK(render(scene, &j, &img, NULL) == PN_OK);
            int win[4];
            pn_image_window(img, win);
            CHECK(win[2] == W && win[3] == H && win[0] + pn_image_width(img) <= W);
            char name[32];
            snprintf(name, sizeof name, "part%d.exr", i);
            snprintf(pathbuf[i], sizeof pathbuf[i], "%s", tmp_path(name));
            names[i] = pathbuf[i];
            CHECK(pn_image_write(ctx, img, names[i], 0) == PN_OK);
            pn_image_free(img);
            CHECK(pn_image_read_layers(ctx, names[i], &parts[i]) == PN_OK);
            int back[4];
            pn_image_window(parts[i], back);
            CHECK(memcmp(win, back, sizeof win) == 0);
        }
        pn_image merged = NULL;
        CHECK(pn_image_merge(ctx, parts, names, 4, &merged) == PN_OK);
        /* Layers read back from EXR come in the file's channel order: compare like with like. */
        pn_image full_back = NULL;
        CHECK(pn_image_read_layers(ctx, tmp_path("full.exr"), &full_back) == PN_OK);
        CHECK_MSG(same_image(full_back, merged), "integrator %d: merged crops differ from the full render",
                  (int)kinds[k]);
        pn_image_free(full_back);
        CHECK(pn_image_write(ctx, merged, tmp_path("merged.exr"), 0) == PN_OK);
        FILE *a = fopen(tmp_path("full.exr"), "rb"), *b = fopen(tmp_path("merged.exr"), "rb");
        int same = a && b;
        for (int ca = 0, cb = 0; same && (ca != EOF || cb != EOF);) {
            ca = fgetc(a);
            cb = fgetc(b);
            same = ca == cb;
        }
        if (a) fclose(a);
        if (b) fclose(b);
        CHECK_MSG(same, "the merged EXR is not the full render's file byte for byte");
        /* Refusals: an overlap, a hole, another display window, other layers. */
        pn_image two[2] = {parts[0], parts[0]};
        const char *two_names[2] = {names[0], names[0]};
        pn_image out = NULL;
        CHECK(pn_image_merge(ctx, two, two_names, 2, &out) == PN_ERROR_BAD_INPUT && out == NULL);
        CHECK_STR_CONTAINS(pn_context_error_message(ctx), "overlaps");
        pn_context_clear_error(ctx);
        CHECK(pn_image_merge(ctx, parts, names, 3, &out) == PN_ERROR_BAD_INPUT);
        CHECK_STR_CONTAINS(pn_context_error_message(ctx), "do not cover");
        pn_context_clear_error(ctx);
        two[1] = full;
        two_names[1] = "full";
        CHECK(pn_image_merge(ctx, two, two_names, 2, &out) == PN_ERROR_BAD_INPUT);
        pn_context_clear_error(ctx);
        pn_image fewer = NULL;
        CHECK(pn_image_crop(ctx, parts[1], 0, 0, pn_image_width(parts[1]), pn_image_height(parts[1]), &fewer) == PN_OK);
        pn_image beauty = NULL;
        CHECK(pn_image_read(ctx, names[1], &beauty) == PN_OK); /* the beauty only, same window */
        two[0] = parts[0];
        two[1] = beauty;
        CHECK(pn_image_merge(ctx, two, two_names, 2, &out) == PN_ERROR_BAD_INPUT);
        pn_context_clear_error(ctx);
        pn_image_free(fewer);
        pn_image_free(beauty);
        for (int i = 0; i < 4; i++) pn_image_free(parts[i]);
        pn_image_free(merged);
        pn_image_free(full);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* --piece K/M parts merge into the full render; tiled renders equal the plain render for block
 * integrators and for contour (bands of rows); illumcut split needs a tile-size, and its parts
 * then merge into the one-process render of the same tile-size. */
static void test_pieces_and_tiles(void) {
    pn_context ctx = new_ctx();
    pn_scene scene = load_demo(ctx);
    if (!scene) {
        CHECK(scene != NULL);
        return;
    }
    const pn_integrator_kind kinds[] = {PN_INTEGRATOR_IAS, PN_INTEGRATOR_CONTOUR, PN_INTEGRATOR_ILLUMCUT};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++) {
        const bool needs_size = kinds[k] == PN_INTEGRATOR_ILLUMCUT;
        pn_image full = NULL;
        if (needs_size) {
            job j = {kinds[k], NULL, {"tile-size", "8", NULL}, 0, 0, ctx};
            CHECK(render(scene, &j, &full, NULL) == PN_OK);
            job bad = {kinds[k], NULL, {"piece", "1/2", NULL}, 0, 0, ctx};
            pn_image none = NULL;
            CHECK(render(scene, &bad, &none, NULL) == PN_ERROR_INVALID_ARGUMENT && none == NULL);
            CHECK_STR_CONTAINS(pn_context_error_message(ctx), "--tile-size");
            pn_context_clear_error(ctx);
        } else {
            full = plain(scene, ctx, kinds[k]);
            job j = {kinds[k], NULL, {"tile-size", "8", NULL}, 0, 0, ctx};
            pn_image tiled = NULL;
            CHECK(render(scene, &j, &tiled, NULL) == PN_OK);
            CHECK_MSG(same_image(full, tiled), "integrator %d: 8-pixel tiles differ from the plain render",
                      (int)kinds[k]);
            pn_image_free(tiled);
        }
        pn_image parts[3] = {NULL};
        const char *names[3] = {"1/3", "2/3", "3/3"};
        for (int i = 0; i < 3; i++) {
            job j = {kinds[k], NULL, {"piece", names[i], "tile-size", "8", NULL}, 0, 0, ctx};
            CHECK_MSG(render(scene, &j, &parts[i], NULL) == PN_OK, "integrator %d, piece %s: %s", (int)kinds[k],
                      names[i], pn_context_error_message(ctx));
        }
        pn_image merged = NULL;
        CHECK(parts[0] && parts[1] && parts[2] && pn_image_merge(ctx, parts, names, 3, &merged) == PN_OK);
        CHECK_MSG(same_image(full, merged), "integrator %d: merged pieces differ from the full render", (int)kinds[k]);
        for (int i = 0; i < 3; i++) pn_image_free(parts[i]);
        pn_image_free(merged);
        pn_image_free(full);
    }
    job j = {PN_INTEGRATOR_REFERENCE, NULL, {"piece", "5/4", NULL}, 0, 0, ctx};
    pn_image none = NULL;
    CHECK(render(scene, &j, &none, NULL) == PN_ERROR_INVALID_ARGUMENT);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static long file_size(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* A render cancelled part way resumes from its checkpoint into the uninterrupted image; a torn
 * last record is dropped; a corrupt record and another render's checkpoint are refused. */
static void test_checkpoint_resume(void) {
    pn_context ctx = new_ctx();
    pn_scene scene = load_demo(ctx);
    if (!scene) {
        CHECK(scene != NULL);
        return;
    }
    const char *ck = tmp_path("render.ckpt");
    unlink(ck);
    job uninterrupted = {PN_INTEGRATOR_LIGHTCUTS, NULL, {NULL}, 0, 0, ctx};
    pn_image full = NULL;
    CHECK(render(scene, &uninterrupted, &full, NULL) == PN_OK);
    job j = {PN_INTEGRATOR_LIGHTCUTS, NULL, {"checkpoint", ck, "tile-size", "8", NULL}, 0, 0.6, ctx};
    pn_image img = NULL;
    pn_stats stats = pn_stats_new();
    double tiles = 0.0, resumed = 0.0;
    CHECK(render(scene, &j, &img, stats) == PN_ERROR_CANCELLED);
    pn_image_free(img);
    pn_context_clear_error(ctx);
    CHECK(pn_stats_get(stats, "tile_count", &tiles));
    const uint32_t count = (uint32_t)tiles;
    CHECK(count == 24);
    /* Resume: only the missing tiles are rendered, and the image is the uninterrupted one. */
    j.cancel_at = 0;
    img = NULL;
    CHECK(render(scene, &j, &img, stats) == PN_OK);
    CHECK(pn_stats_get(stats, "tiles_resumed", &resumed));
    CHECK_MSG(resumed > 0 && resumed < count, "resumed %.0f of %u tiles", resumed, count);
    CHECK_MSG(same_image(full, img), "the resumed render differs from the uninterrupted one");
    pn_image_free(img);
    /* A torn last record (a write cut short by a kill): dropped, its tile rendered again. */
    long size = file_size(ck);
    CHECK(size > 0 && truncate(ck, size - 100) == 0);
    img = NULL;
    CHECK(render(scene, &j, &img, stats) == PN_OK);
    CHECK(pn_stats_get(stats, "tiles_resumed", &resumed) && resumed == count - 1);
    CHECK(same_image(full, img));
    CHECK(file_size(ck) == size);
    pn_image_free(img);
    /* A corrupt record: refused, never mixed in. */
    FILE *f = fopen(ck, "r+b");
    CHECK(f != NULL);
    if (f) {
        fseek(f, size / 2, SEEK_SET);
        int c = fgetc(f);
        fseek(f, size / 2, SEEK_SET);
        fputc(c ^ 0x40, f);
        fclose(f);
    }
    img = NULL;
    CHECK(render(scene, &j, &img, stats) == PN_ERROR_BAD_INPUT && img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "corrupt checkpoint");
    pn_context_clear_error(ctx);
    /* Another render's checkpoint (another seed; other options): refused. */
    unlink(ck);
    CHECK(render(scene, &j, &img, stats) == PN_OK);
    pn_image_free(img);
    img = NULL;
    j.seed = 7;
    CHECK(render(scene, &j, &img, stats) == PN_ERROR_BAD_INPUT && img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "another render");
    pn_context_clear_error(ctx);
    j.seed = 0;
    job other = {PN_INTEGRATOR_LIGHTCUTS, NULL, {"checkpoint", ck, "tile-size", "8", "vpls", "1000", NULL}, 0, 0, ctx};
    CHECK(render(scene, &other, &img, stats) == PN_ERROR_BAD_INPUT && img == NULL);
    pn_context_clear_error(ctx);
    job garbage = {PN_INTEGRATOR_LIGHTCUTS, NULL, {"checkpoint", DEMO, "tile-size", "8", NULL}, 0, 0, ctx};
    CHECK(render(scene, &garbage, &img, stats) == PN_ERROR_BAD_INPUT && img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "not a penumbra checkpoint");
    unlink(ck);
    pn_stats_free(stats);
    pn_image_free(full);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

PN_TESTS(TEST(test_crops_merge_to_full), TEST(test_pieces_and_tiles), TEST(test_checkpoint_resume))
