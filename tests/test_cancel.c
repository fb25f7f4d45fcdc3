/* test_cancel.c — the one cancel and progress path of a render: a cancel issued before a VPL
 * render, or at its first progress report during VPL tracing, ends it with PN_ERROR_CANCELLED
 * before the VPLs are traced (checked by the progress the render reports, not by wall time) and
 * leaves the context usable; progress is monotone, reaches 1 and comes in more than two steps for
 * the tiled driver, illumcut's whole-image phases, contour's scanlines and the progressive drivers; every
 * driver reports its peak memory; `penumbra render` interrupted during VPL tracing exits 130
 * and writes no image at all; contour's trace file is written whole after a finished render only. */
#include "harness.h"

#include "penumbra/penumbra.h"
#include "vpl_scenes.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#ifndef PN_CLI_PATH
#error "PN_CLI_PATH must name the penumbra binary (see tests/CMakeLists.txt)"
#endif

/* What a render reported through its progress callback. */
typedef struct progress_log {
    double values[4096];
    int count;    /* calls (values beyond the array are not kept) */
    int monotone; /* 1 while every value exceeded the one before */
    double last, max;
    pn_context cancel_ctx; /* when set: cancel at the first call */
} progress_log;

static void on_progress(void *user, double fraction) {
    progress_log *log = user;
    if (log->count > 0 && !(fraction > log->last)) log->monotone = 0;
    if (!(fraction >= 0.0 && fraction <= 1.0)) log->monotone = 0;
    if (log->count < 4096) log->values[log->count] = fraction;
    log->count++;
    log->last = fraction;
    if (fraction > log->max) log->max = fraction;
    if (log->cancel_ctx) pn_render_cancel(log->cancel_ctx);
}

static void log_init(progress_log *log) {
    memset(log, 0, sizeof *log);
    log->monotone = 1;
}

/* The options of every render of this file: only "vpls", set anew by settings(). */
static pn_options vpl_options;

static pn_render_settings settings(pn_integrator_kind kind, uint32_t vpls, progress_log *log) {
    pn_render_settings rs;
    memset(&rs, 0, sizeof rs);
    rs.integrator = kind;
    if (!vpl_options) vpl_options = pn_options_new();
    pn_options_unset(vpl_options, "vpls");
    if (vpls) CHECK(pn_options_set_int(NULL, vpl_options, "vpls", vpls) == PN_OK);
    rs.options = vpl_options;
    rs.threads = 2;
    rs.progress = on_progress;
    rs.progress_user = log;
    return rs;
}

/* The VPL tracing phase is the first 8% of the bar (vpl_common.c); 2 million VPLs are traced in
 * steps of 4096 light paths of at most 11 VPLs each, so a render that stops at its first check
 * after a cancel has reported at most 0.08 x 2 x 4096 x 11 / 2e6 = 0.0036 of the bar. */
#define MANY_VPLS 2000000u
#define EARLY_FRACTION 0.004

static void test_cancel_before_render(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room.pbrt", pn_test_room_scene(0, 16, 12));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_integrator_kind kinds[3] = {PN_INTEGRATOR_VPL, PN_INTEGRATOR_LIGHTCUTS, PN_INTEGRATOR_ILLUMCUT};
    for (int k = 0; k < 3; k++) {
        progress_log log;
        log_init(&log);
        pn_render_settings rs = settings(kinds[k], MANY_VPLS, &log);
        pn_image img = NULL;
        pn_render_cancel(ctx);
        CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_ERROR_CANCELLED);
        CHECK(img == NULL);
        CHECK_STR_CONTAINS(pn_context_error_message(ctx), "cancelled");
        /* Nothing was traced: no progress at all. */
        CHECK_MSG(log.count == 0 && log.max == 0.0, "%d calls, up to %g", log.count, log.max);
        pn_context_clear_error(ctx);
    }
    /* The request was consumed: the next render of the context runs to its end. */
    progress_log log;
    log_init(&log);
    pn_render_settings rs = settings(PN_INTEGRATOR_LIGHTCUTS, 2000, &log);
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    CHECK(img != NULL && log.last == 1.0 && log.monotone);
    pn_image_free(img);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_cancel_during_vpl_tracing(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room_t.pbrt", pn_test_room_scene(0, 16, 12));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    pn_integrator_kind kinds[2] = {PN_INTEGRATOR_LIGHTCUTS, PN_INTEGRATOR_ILLUMCUT};
    for (int k = 0; k < 2; k++) {
        progress_log log;
        log_init(&log);
        log.cancel_ctx = ctx; /* Ctrl-C at the first report, a few thousand paths in */
        pn_render_settings rs = settings(kinds[k], MANY_VPLS, &log);
        pn_image img = NULL;
        CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_ERROR_CANCELLED);
        CHECK(img == NULL);
        CHECK_MSG(log.count >= 1 && log.count <= 2 && log.max > 0.0 && log.max < EARLY_FRACTION, "%d calls, up to %g",
                  log.count, log.max);
        pn_context_clear_error(ctx);
    }
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* Monotone, more than two steps, ends at exactly 1. */
static void check_progress(const progress_log *log, const char *what) {
    CHECK_MSG(log->monotone, "%s: not monotone", what);
    CHECK_MSG(log->count > 2, "%s: %d calls", what, log->count);
    CHECK_MSG(log->last == 1.0, "%s: ends at %g", what, log->last);
}

static int values_in(const progress_log *log, double lo, double hi) {
    int n = 0;
    for (int i = 0; i < log->count && i < 4096; i++) n += log->values[i] > lo && log->values[i] < hi;
    return n;
}

static void test_progress_by_phase(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room_p.pbrt", pn_test_room_scene(0, 48, 36));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    /* illumcut renders the window in one call: its phases (eye samples, point tree, Phase I,
     * Phase II) report after the preparation's (VPL tracing, light tree: the first 12%). */
    progress_log log;
    log_init(&log);
    pn_render_settings rs = settings(PN_INTEGRATOR_ILLUMCUT, 60000, &log);
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    pn_image_free(img);
    check_progress(&log, "illumcut");
    CHECK_MSG(values_in(&log, 0.0, 0.08) >= 2, "illumcut: %d reports while tracing", values_in(&log, 0.0, 0.08));
    CHECK_MSG(values_in(&log, 0.12, 0.34) >= 2, "illumcut: %d reports of eye samples", values_in(&log, 0.12, 0.34));
    CHECK_MSG(values_in(&log, 0.47, 1.0) >= 2, "illumcut: %d reports in Phase II", values_in(&log, 0.47, 1.0));
    /* The tiled driver: blocks finishing out of order on two threads still give a monotone bar. */
    log_init(&log);
    rs = settings(PN_INTEGRATOR_LIGHTCUTS, 5000, &log);
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    pn_image_free(img);
    check_progress(&log, "lightcuts");
    CHECK(values_in(&log, 0.12, 1.0) >= 10);
    /* contour's scanline hook (the whole window in one call): row by row. */
    log_init(&log);
    rs = settings(PN_INTEGRATOR_CONTOUR, 0, &log);
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    pn_image_free(img);
    check_progress(&log, "contour");
    CHECK_MSG(log.count >= 30, "contour: %d calls for 36 rows", log.count);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void test_progressive_drivers(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room_d.pbrt", pn_test_room_scene(0, 40, 30));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    /* Every driver of the table reports its peak memory (the tiled one too). */
    pn_driver_kind drivers[5] = {PN_DRIVER_DCM, PN_DRIVER_PAINTER, PN_DRIVER_UNIFORM, PN_DRIVER_FULL,
                                 PN_DRIVER_DEFAULT};
    const char *names[5] = {"dcm", "painter", "uniform", "full", "tiles"};
    for (int d = 0; d < 5; d++) {
        progress_log log;
        log_init(&log);
        pn_render_settings rs = settings(PN_INTEGRATOR_REFERENCE, 0, &log);
        rs.driver = drivers[d];
        rs.spp = 2;
        pn_image img = NULL;
        pn_stats stats = pn_stats_new();
        CHECK_MSG(pn_render(ctx, scene, &rs, &img, stats) == PN_OK, "%s: %s", names[d], pn_context_error_message(ctx));
        pn_image_free(img);
        check_progress(&log, names[d]);
        double peak = 0.0;
        CHECK_MSG(pn_stats_get(stats, "peak_memory_bytes", &peak) && peak > 0.0, "%s: peak memory %.0f", names[d],
                  peak);
        pn_stats_free(stats);
    }
    /* With a VPL integrator: its preparation first, then the driver's pixels. */
    progress_log log;
    log_init(&log);
    pn_render_settings rs = settings(PN_INTEGRATOR_LIGHTCUTS, 5000, &log);
    rs.driver = PN_DRIVER_DCM;
    pn_image img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK);
    pn_image_free(img);
    check_progress(&log, "dcm + lightcuts");
    CHECK(values_in(&log, 0.0, 0.12) >= 1 && values_in(&log, 0.12, 1.0) >= 2);
    /* And a cancel before a progressive render is honoured too. */
    log_init(&log);
    rs = settings(PN_INTEGRATOR_LIGHTCUTS, MANY_VPLS, &log);
    rs.driver = PN_DRIVER_DCM;
    pn_render_cancel(ctx);
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_ERROR_CANCELLED);
    CHECK(img == NULL && log.count == 0);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

/* `penumbra render` of a VPL scene interrupted while it traces VPLs: exit 130, and neither the
 * image nor a NAME.partial.exr (nothing was rendered). Before the cancel path was one, the
 * interrupt was lost at the end of the preparation and the whole image was rendered and written
 * as the partial file. */
static void test_cli_interrupt_during_preparation(void) {
    char scene_path[1100], out_path[512], partial_path[512], err_path[512];
    const char *p = pn_test_write_file(tmpdir, "cli_room.pbrt", pn_test_room_scene(0, 64, 48));
    CHECK(p != NULL);
    if (!p) return;
    snprintf(scene_path, sizeof scene_path, "%s", p);
    snprintf(out_path, sizeof out_path, "%s/cli_room.exr", tmpdir);
    snprintf(partial_path, sizeof partial_path, "%s/cli_room.partial.exr", tmpdir);
    snprintf(err_path, sizeof err_path, "%s/cli.stderr", tmpdir);
    fflush(stdout);
    fflush(stderr);
    pid_t pid = fork();
    CHECK(pid >= 0);
    if (pid < 0) return;
    if (pid == 0) {
        int err_fd = open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        int null_fd = open("/dev/null", O_RDWR);
        if (err_fd < 0 || null_fd < 0) _exit(126);
        dup2(null_fd, STDIN_FILENO);
        dup2(null_fd, STDOUT_FILENO);
        dup2(err_fd, STDERR_FILENO);
        /* 20 million VPLs take tens of seconds to trace: the interrupt lands in the tracing. */
        execl(PN_CLI_PATH, PN_CLI_PATH, "render", scene_path, "--integrator", "lightcuts", "--vpls", "20000000",
              "--threads", "2", "-o", out_path, (char *)NULL);
        _exit(127);
    }
    struct timespec start, now, pause = {0, 5 * 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &start);
    int wstatus = 0, signalled = 0, finished = 0;
    for (;;) {
        pid_t done = waitpid(pid, &wstatus, WNOHANG);
        if (done == pid) {
            finished = 1;
            break;
        }
        if (done < 0 && errno != EINTR) break;
        clock_gettime(CLOCK_MONOTONIC, &now);
        long ms = (long)(now.tv_sec - start.tv_sec) * 1000 + (long)(now.tv_nsec - start.tv_nsec) / 1000000;
        if (!signalled && ms >= 400) {
            kill(pid, SIGINT);
            signalled = 1;
        }
        /* A lost interrupt would trace all 20 million VPLs: stop it and fail. */
        if (ms > 8000) {
            kill(pid, SIGKILL);
            waitpid(pid, &wstatus, 0);
            break;
        }
        nanosleep(&pause, NULL);
    }
    CHECK_MSG(finished, "penumbra did not stop within 8 s of the interrupt");
    CHECK(finished && WIFEXITED(wstatus) && WEXITSTATUS(wstatus) == 130);
    CHECK(access(out_path, F_OK) != 0);
    CHECK(access(partial_path, F_OK) != 0);
}

/* contour-trace is written once the render has finished, in one atomic write: a cancelled render
 * leaves no trace file, a finished one leaves every counted pixel's line, and a trace that cannot
 * be written fails the render with its path (no image). */
static void test_contour_trace_written_whole(void) {
    pn_context ctx = pn_context_new();
    pn_scene scene = vpl_test_load(ctx, "room_c.pbrt", pn_test_room_scene(0, 24, 18));
    if (!scene) {
        pn_context_free(ctx);
        return;
    }
    char trace[512], bad[512];
    snprintf(trace, sizeof trace, "%s/trace.txt", tmpdir);
    snprintf(bad, sizeof bad, "%s/no-such-folder/trace.txt", tmpdir);
    pn_options o = pn_options_new();
    CHECK(pn_options_set(NULL, o, "contour-trace", trace) == PN_OK);
    progress_log log;
    log_init(&log);
    log.cancel_ctx = ctx; /* cancelled at the first row's report */
    pn_render_settings rs = settings(PN_INTEGRATOR_CONTOUR, 0, &log);
    rs.options = o;
    pn_image img = NULL;
    pn_status st = pn_render(ctx, scene, &rs, &img, NULL);
    CHECK(st == PN_OK || st == PN_ERROR_CANCELLED);
    pn_image_free(img);
    pn_context_clear_error(ctx);
    CHECK_MSG(access(trace, F_OK) != 0, "a cancelled render left %s", trace);

    log_init(&log);
    img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_OK && img != NULL);
    pn_image_free(img);
    FILE *f = fopen(trace, "r");
    CHECK(f != NULL);
    int lines = 0, bad_lines = 0;
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        int x, y, cls;
        unsigned why;
        if (sscanf(line, "%d %d %d %u", &x, &y, &cls, &why) != 4 || x < 0 || x >= 24 || y < 0 || y >= 18 || cls < 0 ||
            cls > 3)
            bad_lines++;
        lines++;
    }
    if (f) fclose(f);
    CHECK_MSG(lines > 0 && lines <= 24 * 18 && bad_lines == 0, "%d lines, %d malformed", lines, bad_lines);

    CHECK(pn_options_set(NULL, o, "contour-trace", bad) == PN_OK);
    log_init(&log);
    img = NULL;
    CHECK(pn_render(ctx, scene, &rs, &img, NULL) == PN_ERROR_IO);
    CHECK(img == NULL);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "no-such-folder/trace.txt");
    pn_context_clear_error(ctx);
    pn_options_free(o);
    pn_scene_free(scene);
    pn_context_free(ctx);
}

static void setup(void) {
    vpl_test_setup("cancel");
}

static void teardown(void) {
    pn_options_free(vpl_options);
    vpl_options = NULL;
    vpl_test_teardown();
}

PN_TESTS(TEST(setup), TEST(test_cancel_before_render), TEST(test_cancel_during_vpl_tracing),
         TEST(test_progress_by_phase), TEST(test_progressive_drivers), TEST(test_cli_interrupt_during_preparation),
         TEST(test_contour_trace_written_whole), TEST(teardown))
