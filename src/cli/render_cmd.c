/* render_cmd.c — `penumbra render`: the progress bar, Ctrl-C and SIGUSR1, snapshots, the render
 * itself and the files it writes. */
#include "cli/cli.h"

#include <math.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---------------------------------------------------------------------------------------- */
/* Progress bar */

typedef struct progress_state {
    double start;
    double last_draw;
    int drawn;
    /* progressive drivers (issue 18): evaluated work pixels in percent and the error estimate */
    _Atomic double work_percent, error_estimate; /* < 0: not known */
} progress_state;

static void format_duration(double seconds, char *out, size_t size) {
    if (!(seconds >= 0.0) || seconds > 360000.0) {
        snprintf(out, size, "--:--");
        return;
    }
    long s = (long)(seconds + 0.5);
    if (s >= 3600)
        snprintf(out, size, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
    else
        snprintf(out, size, "%ld:%02ld", s / 60, s % 60);
}

static void draw_progress(progress_state *state, double fraction, double now) {
    enum { BAR_WIDTH = 30 };
    char bar[BAR_WIDTH + 1], elapsed_text[32], eta_text[32];
    if (fraction < 0.0) fraction = 0.0;
    if (fraction > 1.0) fraction = 1.0;
    int filled = (int)(fraction * BAR_WIDTH);
    for (int i = 0; i < BAR_WIDTH; i++) bar[i] = i < filled ? '#' : '.';
    bar[BAR_WIDTH] = '\0';
    double elapsed = now - state->start;
    format_duration(elapsed, elapsed_text, sizeof elapsed_text);
    if (fraction > 0.0)
        format_duration(elapsed * (1.0 - fraction) / fraction, eta_text, sizeof eta_text);
    else
        snprintf(eta_text, sizeof eta_text, "--:--");
    char note[64] = "";
    double wp = atomic_load(&state->work_percent), ee = atomic_load(&state->error_estimate);
    if (wp >= 0.0 && ee >= 0.0)
        snprintf(note, sizeof note, "  work pixels %.1f%%  est. error %.4f", wp, ee);
    else if (wp >= 0.0)
        snprintf(note, sizeof note, "  work pixels %.1f%%", wp);
    fprintf(stderr, "\r[%s] %5.1f%%%s  elapsed %s  ETA %s ", bar, 100.0 * fraction, note, elapsed_text, eta_text);
    fflush(stderr);
    state->drawn = 1;
    state->last_draw = now;
}

/* Called by the library from worker threads, serialised by its lock. */
static void on_progress(void *user, double fraction) {
    progress_state *state = user;
    double now = monotonic_seconds();
    if (state->drawn && now - state->last_draw < 0.1 && fraction < 1.0) return;
    draw_progress(state, fraction, now);
}

/* Called by progressive drivers from the render's thread; drawn with the next bar. */
static void on_progress_note(void *user, double evaluated_percent, double error_estimate) {
    progress_state *state = user;
    atomic_store(&state->work_percent, evaluated_percent);
    atomic_store(&state->error_estimate, error_estimate);
}

static void finish_progress(progress_state *state, int complete) {
    if (!state->drawn) return;
    if (complete) draw_progress(state, 1.0, monotonic_seconds());
    fputc('\n', stderr);
}

/* Signals. SIGINT and SIGTERM are handled from the start of the render until every output is
 * in place or removed: the first asks the render to stop (it finishes its current tiles), the
 * next ends the program at once. A signal while outputs are being written ends the program at
 * once. Before the program ends, the temporaries of the output set being written (if any) are
 * removed, so no "NAME.tmp-PID-N" is ever left behind. */
static pn_context volatile interrupt_context;
static pn_output_set volatile writing_set; /* the set whose temporaries exist now, or NULL */
static volatile sig_atomic_t writing_outputs;
static volatile sig_atomic_t interrupted;

static void on_stop_signal(int signo) {
    static const char note[] = "\npenumbra: interrupted; finishing the current tiles "
                               "(press Ctrl-C again to quit at once)\n";
    if (interrupted || writing_outputs) {
        pn_output_set_discard_temporaries(writing_set);
        signal(signo, SIG_DFL);
        raise(signo);
        return;
    }
    interrupted = 1;
    if (interrupt_context) pn_render_cancel(interrupt_context);
    ssize_t ignored = write(STDERR_FILENO, note, sizeof note - 1);
    (void)ignored;
}

static const int stop_signals[2] = {SIGINT, SIGTERM};

static void install_stop_handlers(struct sigaction previous[2]) {
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_stop_signal;
    sigemptyset(&action.sa_mask);
    for (int i = 0; i < 2; i++) sigaddset(&action.sa_mask, stop_signals[i]);
    for (int i = 0; i < 2; i++) sigaction(stop_signals[i], &action, &previous[i]);
}

static void restore_stop_handlers(const struct sigaction previous[2]) {
    for (int i = 0; i < 2; i++) sigaction(stop_signals[i], &previous[i], NULL);
}

/* Makes `set` the one whose temporaries a signal removes (NULL: none). */
static void set_writing(pn_output_set set) {
    writing_set = set;
}

/* ---------------------------------------------------------------------------------------- */
/* Progressive drivers: snapshots beside the output (out.exr -> out-6pct.exr), written
 * atomically by pn_image_write; SIGUSR1 asks for one. */
typedef struct snapshot_writer {
    const char *image_path, *png_path;
    double exposure;
    int quiet;
} snapshot_writer;

static void snapshot_name(const char *path, double percent, char *out, size_t size) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash)) dot = path + strlen(path);
    snprintf(out, size, "%.*s-%gpct%s", (int)(dot - path), path, percent, dot);
}

static void on_snapshot(void *user, pn_image image, double requested, double evaluated, double seconds) {
    const snapshot_writer *sw = user;
    double percent = requested > 0.0 ? requested : floor(evaluated * 10.0 + 0.5) / 10.0;
    pn_context wctx = pn_context_new();
    pn_output_set set = pn_output_set_new();
    if (!wctx || !set) {
        pn_output_set_free(set);
        pn_context_free(wctx);
        return;
    }
    char paths[2][4096];
    pn_status st = PN_OK;
    set_writing(set);
    for (int i = 0; i < 2 && st == PN_OK; i++) {
        const char *base = i == 0 ? sw->image_path : sw->png_path;
        paths[i][0] = '\0';
        if (!base) continue;
        snapshot_name(base, percent, paths[i], sizeof paths[i]);
        st = pn_output_set_add_image(wctx, set, image, paths[i], (float)sw->exposure);
    }
    if (st == PN_OK) st = pn_output_set_commit(wctx, set);
    set_writing(NULL);
    pn_output_set_free(set);
    if (st != PN_OK)
        fprintf(stderr, "penumbra: cannot write snapshot: %s\n", pn_context_error_message(wctx));
    else if (!sw->quiet)
        for (int i = 0; i < 2; i++)
            if (paths[i][0])
                fprintf(stderr, "penumbra: snapshot %s (%.2f%% of the work pixels, %.2f s)\n", paths[i], evaluated,
                        seconds);
    pn_context_free(wctx);
}

static void on_sigusr1(int signo) {
    (void)signo;
    if (interrupt_context) pn_render_request_snapshot(interrupt_context);
}

/* --aov-png: every single-channel AOV layer as a false-colour PNG with a colour bar, named
 * after the output image: out.exr -> out.passes.png, out.shadow_rays.png, ... added to `set`. */
static pn_status add_aov_pngs(pn_context ctx, pn_output_set set, pn_image image, const char *image_path) {
    const char *dot = strrchr(image_path, '.');
    size_t stem = dot ? (size_t)(dot - image_path) : strlen(image_path);
    for (int l = 1; l < pn_image_layer_count(image); l++) {
        if (pn_image_layer_channels(image, l) != 1) continue;
        const char *name = pn_image_layer_name(image, l);
        char path[4096];
        snprintf(path, sizeof path, "%.*s.%s.png", (int)stem, image_path, name);
        pn_image fc = NULL;
        pn_status st = pn_image_false_color(ctx, image, name, 0.0, 0.0, &fc);
        if (st == PN_OK) st = pn_output_set_add_image(ctx, set, fc, path, 0.0f);
        pn_image_free(fc);
        if (st != PN_OK) return st;
    }
    return PN_OK;
}

/* Writes every output of a finished render as one set: the PNG, the AOV pictures, the
 * statistics and, last, the image, renamed into place only when all were written. */
static int write_outputs(pn_context ctx, pn_output_set set, const render_options *o, const char *image_path,
                         pn_image image, pn_scene scene, const pn_scene_info *info, pn_stats stats) {
    pn_status status = PN_OK;
    /* The exposure only affects PNG files. */
    if (o->png_path) status = pn_output_set_add_image(ctx, set, image, o->png_path, (float)o->exposure);
    if (status == PN_OK && o->aov_png) status = add_aov_pngs(ctx, set, image, image_path);
    if (status != PN_OK) return report_failure(ctx, status);
    if (o->stats_path) {
        int code = write_stats_json(o, set, image_path, scene, info, stats, 0);
        if (code != EXIT_OK) return code;
    }
    status = pn_output_set_add_image(ctx, set, image, image_path, (float)o->exposure);
    if (status == PN_OK) status = pn_output_set_commit(ctx, set);
    return status == PN_OK ? EXIT_OK : report_failure(ctx, status);
}

static int render_main(int argc, char **argv, int rank, int ranks);

/* Under mpirun (docs/distributed.md) every rank runs this command: it joins the MPI job first;
 * only rank 0 shows progress, messages and the summary and writes files (the other ranks' stderr
 * goes to /dev/null; their failures reach rank 0, which names the rank). */
int command_render(int argc, char **argv) {
    pn_context mctx = pn_context_new();
    if (!mctx) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    int rank = 0, ranks = 1;
    pn_status ms = pn_mpi_init(mctx, NULL, NULL, &rank, &ranks);
    if (ms != PN_OK) {
        int code = report_failure(mctx, ms);
        pn_context_free(mctx);
        return code;
    }
    pn_context_free(mctx);
    if (rank > 0 && !freopen("/dev/null", "w", stderr)) return EXIT_SYSTEM;
    int code = render_main(argc, argv, rank, ranks);
    pn_mpi_finalize();
    return code;
}

static int render_main(int argc, char **argv, int rank, int ranks) {
    render_options o;
    memset(&o, 0, sizeof o);
    o.options = pn_options_new();
    if (!o.options) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    int code = parse_render_args(argc, argv, &o);
    if (code >= 0) {
        pn_options_free(o.options);
        return code;
    }
    pn_render_settings *st = &o.settings;

    char *default_name = NULL;
    const char *image_path = o.output_path;
    if (image_path == NULL) {
        default_name = default_output_name(o.scene_path);
        if (default_name == NULL) {
            fprintf(stderr, "penumbra: out of memory\n");
            pn_options_free(o.options);
            return EXIT_SYSTEM;
        }
        image_path = default_name;
    }

    /* Refuse early when an output folder is missing, rather than after the render. */
    if ((code = check_output_folder(image_path)) != EXIT_OK ||
        (o.png_path && (code = check_output_folder(o.png_path)) != EXIT_OK) ||
        (o.stats_path && (code = check_output_folder(o.stats_path)) != EXIT_OK)) {
        free(default_name);
        pn_options_free(o.options);
        return code;
    }

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        free(default_name);
        pn_options_free(o.options);
        return EXIT_SYSTEM;
    }
    log_options log = {o.quiet, 1};
    pn_context_set_log(ctx, on_log, &log);
    pn_context_set_image_pixel_limit(ctx, o.max_image_pixels);

    pn_scene scene = NULL;
    pn_image image = NULL;
    pn_scene_info info;
    pn_stats stats = pn_stats_new();
    memset(&info, 0, sizeof info);
    pn_status status = stats ? pn_scene_load(ctx, o.scene_path, &scene) : PN_ERROR_OUT_OF_MEMORY;
    if (ranks > 1) status = pn_mpi_agree(ctx, status); /* a rank that cannot load ends the job */
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if ((status = pn_scene_get_info(scene, &info)) != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }

    progress_state progress = {monotonic_seconds(), 0.0, 0, -1.0, -1.0};
    if (!o.quiet && rank == 0 && isatty(STDERR_FILENO)) {
        st->progress = on_progress;
        st->progress_user = &progress;
        st->progress_note = on_progress_note;
    }

    struct sigaction previous[2];
    interrupt_context = ctx;
    interrupted = 0;
    writing_outputs = 0;
    install_stop_handlers(previous);
    /* progressive drivers (issue 6): snapshots, and SIGUSR1 for one now */
    snapshot_writer snapshots = {image_path, o.png_path, o.exposure, o.quiet};
    struct sigaction usr1, previous_usr1;
    memset(&usr1, 0, sizeof usr1);
    usr1.sa_handler = on_sigusr1;
    sigemptyset(&usr1.sa_mask);
    const int progressive = (pn_method_get(o.driver)->capabilities & PN_CAP_PROGRESSIVE) != 0;
    if (progressive) {
        st->snapshot = on_snapshot;
        st->snapshot_user = &snapshots;
        sigaction(SIGUSR1, &usr1, &previous_usr1);
    }
    status = pn_render(ctx, scene, st, &image, stats);
    if (progressive) sigaction(SIGUSR1, &previous_usr1, NULL);
    interrupt_context = NULL;
    finish_progress(&progress, status == PN_OK);

    /* From here until the outputs are in place or removed, a signal ends the program at once
     * after removing the temporaries (on_stop_signal). */
    writing_outputs = 1;
    pn_output_set outputs = pn_output_set_new();
    set_writing(outputs);
    if (!outputs) {
        fprintf(stderr, "penumbra: out of memory\n");
        code = EXIT_SYSTEM;
    } else if (rank > 0) { /* rank 0 writes every output */
        code = status == PN_OK                ? EXIT_OK
               : status == PN_ERROR_CANCELLED ? EXIT_INTERRUPTED
                                              : report_failure(ctx, status);
    } else if (status == PN_ERROR_CANCELLED || (status == PN_OK && interrupted)) {
        /* The user asked to stop: keep what was rendered, but never under the requested name,
         * where it could be mistaken for a finished image. */
        fprintf(stderr, "penumbra: interrupted; the partial image was not written to '%s'\n", image_path);
        char *partial_path = image ? partial_output_name(image_path) : NULL;
        int partial_written = 0;
        if (partial_path) {
            pn_context_clear_error(ctx);
            partial_written = pn_output_set_add_image(ctx, outputs, image, partial_path, (float)o.exposure) == PN_OK;
        }
        if (o.stats_path) write_stats_json(&o, outputs, partial_written ? partial_path : NULL, scene, &info, stats, 1);
        if (pn_output_set_commit(ctx, outputs) == PN_OK && partial_written)
            fprintf(stderr, "penumbra: what was rendered is in '%s'\n", partial_path);
        free(partial_path);
        code = EXIT_INTERRUPTED;
    } else if (status != PN_OK) {
        code = report_failure(ctx, status);
    } else {
        code = write_outputs(ctx, outputs, &o, image_path, image, scene, &info, stats);
        if (code == EXIT_OK && !o.quiet) print_render_summary(&o, &info, stats, image_path);
    }
    /* Whatever was not renamed into place is removed before the handlers go. */
    set_writing(NULL);
    pn_output_set_free(outputs);
    writing_outputs = 0;
    restore_stop_handlers(previous);

done:
    pn_stats_free(stats);
    pn_image_free(image);
    pn_scene_free(scene);
    pn_context_free(ctx);
    pn_options_free(o.options);
    free(default_name);
    return code;
}
