/* test_alloc_failures.c — allocation-failure injection (issue 19; built only by `make sanitize`,
 * where core/alloc_hook.h routes every library allocation through a counter).
 *
 * One clean run counts the allocations T of: a context, loading the demo scene (scenes/demo:
 * parser, PLY-free meshes, lights, materials, Embree scene), a 16x12 render at 1 eye ray per
 * pixel, and writing it as EXR and PNG through one output set. Then the run is repeated with the
 * N-th allocation failing, for every N up to 64 and a spread of N up to T (about 100 runs), one
 * thread so that the allocation order is the same in every run. Each run must end with an error
 * status (never PN_OK with a failed allocation, never a crash); ASan's leak check at exit (the
 * sanitizer build's ctest runs with detect_leaks=1) covers every failing path. */
#define PN_SCENE_FILES_PREFIX "pn_test_alloc"
#include "harness.h"
#include "scene_files.h"

#include "core/alloc_hook.h"

#include <penumbra/penumbra.h>

#ifndef PN_ALLOC_HOOK
#error "test_alloc_failures needs the PN_SANITIZE build (core/alloc_hook.h)"
#endif

/* Load, render, write; returns the first failing status (PN_ERROR_OUT_OF_MEMORY when even the
 * context could not be made). */
static pn_status load_render_write(void) {
    pn_context ctx = pn_context_new();
    if (!ctx) return PN_ERROR_OUT_OF_MEMORY;
    pn_context_set_log(ctx, silent_log, NULL);
    pn_scene scene = NULL;
    pn_image image = NULL;
    pn_output_set set = NULL;
    pn_status st = pn_scene_load(ctx, PN_SOURCE_DIR "/scenes/demo/demo.pbrt", &scene);
    if (st == PN_OK) {
        pn_render_settings s = {.width = 16, .height = 12, .spp = 1, .threads = 1};
        st = pn_render(ctx, scene, &s, &image, NULL);
    }
    int reported_by_null = 0; /* pn_output_set_new says "out of memory" by returning NULL */
    if (st == PN_OK) {
        set = pn_output_set_new();
        reported_by_null = set == NULL;
        st = set ? pn_output_set_add_image(ctx, set, image, tpath("out.exr"), 0.0f) : PN_ERROR_OUT_OF_MEMORY;
    }
    if (st == PN_OK) st = pn_output_set_add_image(ctx, set, image, tpath("out.png"), 0.0f);
    if (st == PN_OK) st = pn_output_set_commit(ctx, set);
    /* A failure must leave a message behind, whatever it was. */
    if (st != PN_OK && !reported_by_null && pn_context_error_message(ctx)[0] == '\0') st = PN_ERROR_INTERNAL;
    pn_output_set_free(set);
    pn_image_free(image);
    pn_scene_free(scene);
    pn_context_free(ctx);
    return st;
}

static void test_every_sampled_failure_is_reported(void) {
    pn_alloc_hook_fail_at(0);
    CHECK(load_render_write() == PN_OK);
    long total = pn_alloc_hook_count();
    CHECK(total > 100);
    /* Every N while that stays within a few seconds (a run takes a few ms), else a spread. */
    long step = total > 2000 ? (total - 64) / 1000 + 1 : 1;
    int runs = 0, swallowed = 0, silent = 0;
    for (long n = 1; n <= total; n = n < 64 ? n + 1 : n + step) {
        pn_alloc_hook_fail_at(n);
        pn_status st = load_render_write();
        int failed = pn_alloc_hook_failed();
        pn_alloc_hook_fail_at(0);
        runs++;
        if (!failed) continue; /* fewer allocations in this run: nothing was injected */
        if (st == PN_OK) {
            swallowed++;
            fprintf(stderr, "  allocation %ld of %ld failed but the run succeeded\n", n, total);
        }
        if (st == PN_ERROR_INTERNAL) {
            silent++;
            fprintf(stderr, "  allocation %ld of %ld failed with no message\n", n, total);
        }
    }
    printf("allocation failures: %d runs over %ld allocations, %d reported as success, %d without a message\n", runs,
           total, swallowed, silent);
    CHECK(swallowed == 0);
    CHECK(silent == 0);
}

PN_TESTS(TEST(test_every_sampled_failure_is_reported))
