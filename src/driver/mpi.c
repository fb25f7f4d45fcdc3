/* mpi.c — rendering across MPI ranks (docs/distributed.md; ARCHITECTURE.md "Beyond one machine").
 *
 * Every rank loads the scene and prepares the integrator itself (VPLs, light trees: built from
 * the seed, so identically on every rank; the tests compare images bit for bit). Rank 0 hands the
 * tiles of the window out one at a time, in order, to whichever rank asks (dynamic scheduling, so
 * that expensive tiles do not leave ranks idle), renders tiles too on a thread of its own, stores
 * what comes back, records it in the checkpoint, and writes the image. A worker's reply to a tile
 * is its packed pixel estimates, which carry every per-pixel counter, so rank 0's statistics are
 * those of the whole image; what integrators count on their own is summed by
 * pn_dist_reduce_stats.
 *
 * Messages (MPI_COMM_WORLD, raw bytes: the ranks run the same binary on one kind of machine):
 *   worker -> 0, TAG_ASK: a header (what: first request, a finished tile, or a failure with its
 *     message; the rank's busy seconds so far) followed, for a finished tile, by its estimates;
 *   0 -> worker, TAG_TILE: the next tile's index, or -1: stop.
 * Only the main thread of a rank calls MPI (MPI_THREAD_FUNNELED). Rank 0's main thread polls
 * (MPI_Iprobe, then a sleep from 50 us doubling up to 1 ms while nothing comes: with 100 us
 * sleeps its ~10^4 wake-ups a second cost 0.1 s of CPU on a 2 s render), so that it leaves the
 * core to the renderer thread; a worker waits for its next tile with MPI_Test every 50 us (in
 * MPI_Recv it would spin a core).
 *
 * Failure: a rank that cannot load the scene or prepare reports it in the first collective
 * (pn_mpi_agree, pn_dist_start), and every rank stops with rank 0 printing "rank R: message";
 * a rank that fails a tile sends its message and is told to stop, and so is everyone else; a
 * rank that dies takes the job down through mpirun. Tiles are recorded in the checkpoint as they
 * arrive, so what was finished survives all three.
 *
 * Built without MPI (PN_HAVE_MPI undefined), every function here is the one-process case. */
#include "core/context.h"
#include "driver/tiles.h"
#include "render/progress.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef PN_HAVE_MPI
#include <mpi.h>
#include <pthread.h>
#include <time.h>
#endif

/* MPI is per process: MPI_Init once, MPI_COMM_WORLD for every render of the process. */
static int world_rank, world_size = 1;

int pn_dist_size(void) {
    return world_size;
}
int pn_dist_rank(void) {
    return world_rank;
}

int pn_mpi_available(void) {
#ifdef PN_HAVE_MPI
    return 1;
#else
    return 0;
#endif
}

/* The launcher's word on how many processes the job has (Open MPI, PMIx, MPICH's PMI). */
static int launched_size(void) {
    const char *names[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_SIZE", "PMI_SIZE"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        const char *v = getenv(names[i]);
        if (v && atoi(v) > 0) return atoi(v);
    }
    return getenv("PMIX_RANK") ? 2 : 1;
}

#ifndef PN_HAVE_MPI

pn_status pn_mpi_init(pn_context ctx, int *argc, char ***argv, int *rank, int *size) {
    (void)argc;
    (void)argv;
    if (rank) *rank = 0;
    if (size) *size = 1;
    if (launched_size() > 1)
        return pn_context_fail(ctx, PN_ERROR_UNSUPPORTED,
                               "penumbra was built without MPI, but was started as one of %d MPI processes; rebuild "
                               "it with Open MPI installed (scripts/install-deps.sh) or run it without mpirun",
                               launched_size());
    return PN_OK;
}
pn_status pn_mpi_agree(pn_context ctx, pn_status local) {
    (void)ctx;
    return local;
}
void pn_mpi_finalize(void) {}
pn_status pn_dist_start(pn_context ctx, pn_status local, uint64_t key) {
    (void)ctx;
    (void)key;
    return local;
}
pn_status pn_dist_run_tiles(pn_context ctx, pn_tile_work *work, pn_dist_report *report) {
    (void)work;
    (void)report;
    return pn_context_fail(ctx, PN_ERROR_INTERNAL, "pn_dist_run_tiles without MPI");
}
void pn_dist_reduce_stats(pn_render_stats *stats) {
    (void)stats;
}

#else

enum { TAG_ASK = 1601, TAG_TILE = 1602, TAG_AGREE = 1603 };
enum { ASK_FIRST = 0, ASK_RESULT = 1, ASK_FAILED = 2 };
/* Rank 0's sleep between polls when no message came: from 50 us, doubling up to 1 ms. */
#define POLL_MIN_NS 50000L
#define POLL_MAX_NS 1000000L

typedef struct ask_header {
    int32_t what, tile, status, pad;
    double busy_seconds;
    char message[512];
} ask_header;

static int initialised_here;

pn_status pn_mpi_init(pn_context ctx, int *argc, char ***argv, int *rank, int *size) {
    if (rank) *rank = 0;
    if (size) *size = 1;
    if (launched_size() <= 1 && !getenv("OMPI_COMM_WORLD_SIZE")) return PN_OK; /* not under mpirun */
    int provided = 0, already = 0;
    MPI_Initialized(&already);
    if (!already) {
        if (MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) != MPI_SUCCESS)
            return pn_context_fail(ctx, PN_ERROR_UNSUPPORTED, "MPI_Init_thread failed");
        initialised_here = 1;
    } else {
        MPI_Query_thread(&provided);
    }
    if (provided < MPI_THREAD_FUNNELED)
        return pn_context_fail(ctx, PN_ERROR_UNSUPPORTED,
                               "the MPI library offers no MPI_THREAD_FUNNELED (threads beside the MPI thread)");
    MPI_Comm_rank(MPI_COMM_WORLD, &world_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &world_size);
    if (rank) *rank = world_rank;
    if (size) *size = world_size;
    return PN_OK;
}

void pn_mpi_finalize(void) {
    int done = 0;
    if (initialised_here && (MPI_Finalized(&done), !done)) MPI_Finalize();
    initialised_here = 0;
}

/* Every rank's status; the failing ranks' messages go to rank 0, whose context then reads
 * "rank R of N: message" for the first of them. The first failure's status on every rank. */
pn_status pn_mpi_agree(pn_context ctx, pn_status local) {
    if (world_size <= 1) return local;
    int *all = calloc((size_t)world_size, sizeof *all);
    if (!all) MPI_Abort(MPI_COMM_WORLD, 4);
    int mine = (int)local;
    MPI_Allgather(&mine, 1, MPI_INT, all, 1, MPI_INT, MPI_COMM_WORLD);
    char message[1024];
    snprintf(message, sizeof message, "%s", pn_context_error_message(ctx));
    if (local != PN_OK && world_rank != 0)
        MPI_Send(message, (int)sizeof message, MPI_CHAR, 0, TAG_AGREE, MPI_COMM_WORLD);
    pn_status result = PN_OK;
    int first = -1;
    for (int r = 0; r < world_size; r++)
        if (all[r] != PN_OK && first < 0) {
            first = r;
            result = (pn_status)all[r];
        }
    if (world_rank == 0) {
        char text[1024], first_text[1024] = "";
        for (int r = 1; r < world_size; r++)
            if (all[r] != PN_OK) {
                MPI_Recv(text, (int)sizeof text, MPI_CHAR, r, TAG_AGREE, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                if (r == first) snprintf(first_text, sizeof first_text, "%s", text);
            }
        if (first == 0) snprintf(first_text, sizeof first_text, "%s", message);
        if (first >= 0) {
            pn_context_clear_error(ctx);
            pn_context_fail(ctx, result, "rank %d of %d: %s", first, world_size, first_text);
        }
    } else if (result != PN_OK && local == PN_OK) {
        pn_context_fail(ctx, result, "rank %d failed", first);
    }
    free(all);
    return result;
}

pn_status pn_dist_start(pn_context ctx, pn_status local, uint64_t key) {
    pn_status st = pn_mpi_agree(ctx, local);
    if (st != PN_OK) return st;
    unsigned long long mine = key, *keys = calloc((size_t)world_size, sizeof *keys);
    if (!keys) MPI_Abort(MPI_COMM_WORLD, 4);
    MPI_Allgather(&mine, 1, MPI_UNSIGNED_LONG_LONG, keys, 1, MPI_UNSIGNED_LONG_LONG, MPI_COMM_WORLD);
    for (int r = 1; r < world_size && st == PN_OK; r++)
        if (keys[r] != keys[0])
            st = pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT,
                                 "rank %d of %d renders another scene or other settings than rank 0 (their render keys "
                                 "differ): every rank must run the same command on the same files",
                                 r, world_size);
    free(keys);
    return st;
}

static double now_seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Rank 0's shared state: the next tile, what failed, what each rank did. */
typedef struct dealer {
    pn_tile_work *work;
    pthread_mutex_t lock;
    int next;
    pn_status failed;
    char failure[1024];
    int failed_rank;
    pn_dist_report *report;
    int stored;
} dealer;

/* The next tile nobody has, or -1 (all handed out, or the render is stopping). Under the lock. */
static int deal(dealer *d) {
    if (d->failed != PN_OK || atomic_load(d->work->cancel)) return -1;
    while (d->next < d->work->grid->count && d->work->done[d->next]) d->next++;
    return d->next < d->work->grid->count ? d->next++ : -1;
}

static void fail_locked(dealer *d, int rank, pn_status st, const char *message) {
    if (d->failed != PN_OK) return;
    d->failed = st;
    d->failed_rank = rank;
    snprintf(d->failure, sizeof d->failure, "%s", message);
}

/* Rank 0's own renderer thread: tiles from the same dealer as the workers. */
static void *local_renderer(void *user) {
    dealer *d = user;
    pn_tile_work *w = d->work;
    pn_pixel_estimate *pack = malloc(w->max_tile_pixels * sizeof *pack);
    for (;;) {
        pthread_mutex_lock(&d->lock);
        int tile = pack ? deal(d) : -1;
        if (!pack) fail_locked(d, 0, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        pthread_mutex_unlock(&d->lock);
        if (tile < 0) break;
        double t0 = now_seconds();
        pn_status st = w->render(w->user, tile, pack);
        double t1 = now_seconds();
        pthread_mutex_lock(&d->lock);
        d->report->busy_seconds[0] += t1 - t0;
        if (st == PN_OK) st = w->store(w->user, tile, pack, true);
        if (st == PN_OK) {
            d->report->tiles[0]++;
            d->stored++;
        } else {
            fail_locked(d, 0, st, pn_status_string(st));
        }
        pthread_mutex_unlock(&d->lock);
    }
    free(pack);
    return NULL;
}

static pn_status run_rank0(pn_context ctx, pn_tile_work *w, pn_dist_report *report) {
    dealer d;
    memset(&d, 0, sizeof d);
    d.work = w;
    d.report = report;
    pthread_mutex_init(&d.lock, NULL);
    size_t cap = sizeof(ask_header) + w->max_tile_pixels * sizeof(pn_pixel_estimate);
    char *buf = malloc(cap);
    pthread_t thread;
    bool thread_ok = buf && pthread_create(&thread, NULL, local_renderer, &d) == 0;
    if (!thread_ok) fail_locked(&d, 0, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    int active = world_size - 1;
    long pause_ns = POLL_MIN_NS;
    while (active > 0) {
        int flag = 0;
        MPI_Status status;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_ASK, MPI_COMM_WORLD, &flag, &status);
        if (!flag) {
            /* Idle: sleep, twice as long each time up to POLL_MAX_NS (few wake-ups while tiles
             * render), back to POLL_MIN_NS once a message came (quick answers when ranks ask). */
            struct timespec pause = {0, pause_ns};
            nanosleep(&pause, NULL);
            pause_ns = pause_ns * 2 < POLL_MAX_NS ? pause_ns * 2 : POLL_MAX_NS;
            continue;
        }
        pause_ns = POLL_MIN_NS;
        int bytes = 0;
        MPI_Get_count(&status, MPI_BYTE, &bytes);
        int src = status.MPI_SOURCE;
        if (!buf || (size_t)bytes > cap || bytes < (int)sizeof(ask_header)) {
            /* Not a message of ours: take it off the queue and stop that rank. */
            char sink[1];
            MPI_Recv(buf && (size_t)bytes <= cap ? buf : sink, buf && (size_t)bytes <= cap ? bytes : 0, MPI_BYTE, src,
                     TAG_ASK, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
            pthread_mutex_lock(&d.lock);
            fail_locked(&d, src, PN_ERROR_INTERNAL, "a message of the wrong size");
            pthread_mutex_unlock(&d.lock);
        } else {
            MPI_Recv(buf, bytes, MPI_BYTE, src, TAG_ASK, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        }
        ask_header h;
        memcpy(&h, buf ? buf : (char *)&h, sizeof h);
        pthread_mutex_lock(&d.lock);
        if (src < PN_DIST_MAX_RANKS) report->busy_seconds[src] = h.busy_seconds;
        if (h.what == ASK_RESULT && h.tile >= 0 && h.tile < w->grid->count &&
            (size_t)bytes == sizeof h + pn_tile_pixel_count(w->grid, h.tile) * sizeof(pn_pixel_estimate)) {
            pn_status st = w->store(w->user, h.tile, (const pn_pixel_estimate *)(void *)(buf + sizeof h), false);
            if (st != PN_OK) fail_locked(&d, 0, st, pn_context_error_message(ctx));
            if (src < PN_DIST_MAX_RANKS) report->tiles[src]++;
            d.stored++;
        } else if (h.what == ASK_FAILED) {
            h.message[sizeof h.message - 1] = '\0';
            fail_locked(&d, src, (pn_status)h.status, h.message);
        }
        int32_t tile = deal(&d);
        int stored = d.stored;
        pthread_mutex_unlock(&d.lock);
        pn_progress_report(w->progress, (double)stored / (double)w->grid->count);
        MPI_Send(&tile, 1, MPI_INT32_T, src, TAG_TILE, MPI_COMM_WORLD);
        if (tile < 0) active--;
    }
    if (thread_ok) pthread_join(thread, NULL);
    free(buf);
    pthread_mutex_destroy(&d.lock);
    if (d.failed == PN_OK) return PN_OK;
    if (d.failed == PN_ERROR_CANCELLED) return PN_ERROR_CANCELLED;
    if (d.failed_rank == 0 && pn_context_error_message(ctx)[0]) return d.failed;
    return pn_context_fail(ctx, d.failed, "rank %d of %d: %s", d.failed_rank, world_size, d.failure);
}

/* A worker's wait for its next tile: tested every 50 us rather than in MPI_Recv, which spins a
 * core (on an oversubscribed machine, the one rank 0 needs to answer). */
static void wait_for_tile(int32_t *tile) {
    MPI_Request request;
    MPI_Irecv(tile, 1, MPI_INT32_T, 0, TAG_TILE, MPI_COMM_WORLD, &request);
    for (;;) {
        int done = 0;
        MPI_Test(&request, &done, MPI_STATUS_IGNORE);
        if (done) return;
        struct timespec pause = {0, 50000};
        nanosleep(&pause, NULL);
    }
}

static pn_status run_worker(pn_context ctx, pn_tile_work *w) {
    size_t cap = sizeof(ask_header) + w->max_tile_pixels * sizeof(pn_pixel_estimate);
    char *buf = malloc(cap);
    ask_header h;
    memset(&h, 0, sizeof h);
    h.what = buf ? ASK_FIRST : ASK_FAILED;
    h.status = buf ? PN_OK : PN_ERROR_OUT_OF_MEMORY;
    if (!buf) snprintf(h.message, sizeof h.message, "out of memory");
    size_t bytes = sizeof h;
    pn_status result = (pn_status)h.status;
    double busy = 0.0;
    for (;;) {
        h.busy_seconds = busy;
        if (buf) memcpy(buf, &h, sizeof h);
        MPI_Send(buf ? buf : (char *)&h, (int)bytes, MPI_BYTE, 0, TAG_ASK, MPI_COMM_WORLD);
        int32_t tile = -1;
        wait_for_tile(&tile);
        if (tile < 0 || h.what == ASK_FAILED) break;
        double t0 = now_seconds();
        pn_status st = w->render(w->user, tile, (pn_pixel_estimate *)(void *)(buf + sizeof h));
        busy += now_seconds() - t0;
        memset(&h, 0, sizeof h);
        h.tile = tile;
        if (st == PN_OK) {
            h.what = ASK_RESULT;
            bytes = sizeof h + pn_tile_pixel_count(w->grid, tile) * sizeof(pn_pixel_estimate);
        } else {
            h.what = ASK_FAILED;
            h.status = st;
            const char *m = pn_context_error_message(ctx);
            snprintf(h.message, sizeof h.message, "%s", m[0] ? m : pn_status_string(st));
            bytes = sizeof h;
            result = st;
        }
    }
    free(buf);
    return result;
}

pn_status pn_dist_run_tiles(pn_context ctx, pn_tile_work *work, pn_dist_report *report) {
    report->ranks = world_size;
    pn_status st = world_rank == 0 ? run_rank0(ctx, work, report) : run_worker(ctx, work);
    return st;
}

void pn_dist_reduce_stats(pn_render_stats *s) {
    /* What integrators count themselves (not per pixel): totals over the ranks, the entries the
     * statistics table (render/stats.c) marks rank_sum. */
    enum { N = 64 };
    const pn_stat_decl *decls[N];
    double mine[N], sum[N];
    int n = 0;
    for (int i = 0; i < pn_stats_decl_count() && n < N; i++) {
        const pn_stat_decl *d = pn_stats_decl(i);
        if (!d->rank_sum) continue;
        decls[n] = d;
        mine[n++] = pn_stats_value(s, d);
    }
    MPI_Reduce(mine, sum, n, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    if (world_rank != 0) return;
    for (int i = 0; i < n; i++) pn_stats_store(s, decls[i], sum[i]);
}

#endif
