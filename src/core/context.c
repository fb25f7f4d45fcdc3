/* context.c — context creation, error keeping and logging. */
#include "core/context.h"
#include "core/text.h"

#include <stdio.h>
#include <stdlib.h>

static void default_log(void *user, pn_log_level level, const char *message) {
    (void)user;
    if (level == PN_LOG_INFO) return;
    fprintf(stderr, "penumbra: %s: %s\n", level == PN_LOG_WARNING ? "warning" : "error", message);
}

pn_context pn_context_new(void) {
    pn_context ctx = calloc(1, sizeof *ctx);
    if (!ctx) return NULL;
    pn_err_init(&ctx->err);
    ctx->log_fn = default_log;
    atomic_init(&ctx->cancel, 0);
    atomic_init(&ctx->snapshot_request, 0);
    return ctx;
}

void pn_context_free(pn_context ctx) {
    free(ctx);
}

void pn_context_set_log(pn_context ctx, pn_log_fn fn, void *user) {
    if (!ctx) return;
    ctx->log_fn = fn ? fn : default_log;
    ctx->log_user = fn ? user : NULL;
}

const char *pn_context_error_message(pn_context ctx) {
    return ctx ? ctx->err.message : "";
}

void pn_context_clear_error(pn_context ctx) {
    if (ctx) pn_err_init(&ctx->err);
}

pn_status pn_context_fail_from(pn_context ctx, const pn_err *err) {
    if (!err || err->status == PN_OK) return PN_OK;
    if (ctx) pn_err_set(&ctx->err, err->status, "%s", err->message);
    return err->status;
}

pn_status pn_context_fail(pn_context ctx, pn_status status, const char *fmt, ...) {
    if (!ctx) return status;
    va_list ap;
    va_start(ap, fmt);
    pn_err_setv(&ctx->err, status, fmt, ap);
    va_end(ap);
    return status;
}

void pn_context_log(pn_context ctx, pn_log_level level, const char *fmt, ...) {
    if (!ctx || !ctx->log_fn) return;
    char raw[2048], buf[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(raw, sizeof raw, fmt, ap);
    va_end(ap);
    ctx->log_fn(ctx->log_user, level, pn_text_escape(buf, sizeof buf, raw));
}

void pn_render_cancel(pn_context ctx) {
    if (ctx) atomic_store(&ctx->cancel, 1);
}
