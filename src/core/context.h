/* context.h — the library context: first error, log callback, cancel flag. No globals. */
#ifndef PN_CORE_CONTEXT_H
#define PN_CORE_CONTEXT_H

#include "core/error.h"
#include <stdatomic.h>
#include <stdint.h>

struct pn_context_s {
    pn_err err;
    pn_log_fn log_fn;
    void *log_user;
    atomic_int cancel;
    atomic_int snapshot_request; /* progressive drivers: pn_render_request_snapshot */
    uint64_t image_pixel_limit;  /* pn_context_set_image_pixel_limit; 0 = the default */
};

/* Copies a failure recorded in `err` into the context (first error wins) and returns its status. */
pn_status pn_context_fail_from(pn_context ctx, const pn_err *err);
/* Records a failure on the context directly. */
pn_status pn_context_fail(pn_context ctx, pn_status status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* Sends a message to the log callback. */
void pn_context_log(pn_context ctx, pn_log_level level, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#endif
