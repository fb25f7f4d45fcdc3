/* progress.c — the one progress and cancel path of a render (see progress.h), and the peak
 * memory every driver reports. */
#include "render/progress.h"

#include <sys/resource.h>

void pn_progress_init(pn_progress *p, void (*fn)(void *user, double fraction), void *user, const atomic_int *cancel) {
    p->fn = fn;
    p->user = user;
    pthread_mutex_init(&p->lock, NULL);
    p->reported = 0.0;
    p->window_start = p->phase_start = 0.0;
    p->window_end = p->phase_end = 1.0;
    p->cancel = cancel;
}

void pn_progress_destroy(pn_progress *p) {
    if (p) pthread_mutex_destroy(&p->lock);
}

void pn_progress_window(pn_progress *p, double start, double end) {
    if (!p) return;
    pthread_mutex_lock(&p->lock);
    p->window_start = p->phase_start = start;
    p->window_end = p->phase_end = end;
    pthread_mutex_unlock(&p->lock);
}

void pn_progress_phase(pn_progress *p, double start, double end) {
    if (!p) return;
    pthread_mutex_lock(&p->lock);
    double w = p->window_end - p->window_start;
    p->phase_start = p->window_start + w * start;
    p->phase_end = p->window_start + w * end;
    pthread_mutex_unlock(&p->lock);
}

void pn_progress_report(pn_progress *p, double fraction) {
    if (!p || !p->fn) return;
    if (!(fraction > 0.0)) fraction = 0.0;
    if (fraction > 1.0) fraction = 1.0;
    pthread_mutex_lock(&p->lock);
    double v = p->phase_start + (p->phase_end - p->phase_start) * fraction;
    if (v > 1.0) v = 1.0;
    /* Only forward progress reaches the callback (threads finish out of order). */
    if (v > p->reported) {
        p->reported = v;
        p->fn(p->user, v);
    }
    pthread_mutex_unlock(&p->lock);
}

double pn_progress_value(pn_progress *p) {
    if (!p) return 0.0;
    pthread_mutex_lock(&p->lock);
    double v = p->reported;
    pthread_mutex_unlock(&p->lock);
    return v;
}

bool pn_progress_cancelled(const pn_progress *p) {
    return p && p->cancel && atomic_load(p->cancel) != 0;
}

bool pn_progress_step(void *progress, double fraction) {
    pn_progress *p = progress;
    pn_progress_report(p, fraction);
    return !pn_progress_cancelled(p);
}

uint64_t pn_peak_memory_bytes(void) {
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0;
    return (uint64_t)ru.ru_maxrss * 1024u; /* Linux reports kilobytes */
}
