/* progress.h — the one progress and cancel path of a render: every driver and every integrator
 * that runs a phase of its own (VPL tracing, light trees, illumcut's point tree and passes)
 * reports through it, so that the callback of pn_render_settings sees one monotone fraction
 * that reaches 1, whatever the driver.
 *
 * Phases: the render is cut into windows of [0, 1]. A window is set with pn_progress_window
 * (absolute fractions); pn_progress_phase picks a part of the current window (fractions of
 * it), and pn_progress_report says how far the current phase is (a fraction of it). Reports are
 * serialised by a lock and only a value above the last one reaches the callback, so that the
 * callback never sees the bar go back when worker threads finish out of order.
 *
 * The weights of the phases are fixed shares (not measured times): a bar, not a clock. */
#ifndef PN_RENDER_PROGRESS_H
#define PN_RENDER_PROGRESS_H

#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdint.h>

typedef struct pn_progress {
    void (*fn)(void *user, double fraction); /* NULL: nothing is reported */
    void *user;
    pthread_mutex_t lock;
    double reported;                 /* the last value passed to fn (0 before the first) */
    double window_start, window_end; /* the current window (absolute) */
    double phase_start, phase_end;   /* the current phase (absolute, inside the window) */
    const atomic_int *cancel;        /* the context's cancel flag */
} pn_progress;

/* A progress path over the callback (may be NULL) and the cancel flag; window and phase [0, 1]. */
void pn_progress_init(pn_progress *p, void (*fn)(void *user, double fraction), void *user, const atomic_int *cancel);
void pn_progress_destroy(pn_progress *p);
/* Sets the window to [start, end] (absolute) and the phase to the whole window. */
void pn_progress_window(pn_progress *p, double start, double end);
/* Sets the phase to [start, end] as fractions of the current window. */
void pn_progress_phase(pn_progress *p, double start, double end);
/* Reports that the current phase is `fraction` done (clamped to [0, 1]). Thread-safe. */
void pn_progress_report(pn_progress *p, double fraction);
/* The last value reported (absolute). */
double pn_progress_value(pn_progress *p);
/* True when the render has been asked to stop. */
bool pn_progress_cancelled(const pn_progress *p);
/* A bool(void *, double) callback for modules that must not see the driver (lights/vpl.c):
 * reports `fraction` of the current phase and returns false when the render is cancelled. */
bool pn_progress_step(void *progress, double fraction);

/* Peak resident memory of the process so far (getrusage), in bytes; 0 if unknown. */
uint64_t pn_peak_memory_bytes(void);

#endif
