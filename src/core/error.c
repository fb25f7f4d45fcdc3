/* error.c — first-error-wins status recording and the status string table. */
#include "core/error.h"
#include "core/text.h"

#include <stdio.h>
#include <string.h>

void pn_err_init(pn_err *err) {
    err->status = PN_OK;
    err->message[0] = '\0';
}

pn_status pn_err_setv(pn_err *err, pn_status status, const char *fmt, va_list ap) {
    if (err == NULL || status == PN_OK) return status;
    if (err->status != PN_OK) return status;
    err->status = status;
    /* One line, control bytes escaped: messages quote text from files (core/text.h). */
    char raw[sizeof err->message];
    vsnprintf(raw, sizeof raw, fmt, ap);
    pn_text_escape(err->message, sizeof err->message, raw);
    return status;
}

pn_status pn_err_set(pn_err *err, pn_status status, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    pn_err_setv(err, status, fmt, ap);
    va_end(ap);
    return status;
}

const char *pn_status_string(pn_status status) {
    switch (status) {
    case PN_OK: return "ok";
    case PN_ERROR_INVALID_ARGUMENT: return "invalid argument";
    case PN_ERROR_BAD_INPUT: return "bad input";
    case PN_ERROR_IO: return "input/output error";
    case PN_ERROR_OUT_OF_MEMORY: return "out of memory";
    case PN_ERROR_UNSUPPORTED: return "unsupported";
    case PN_ERROR_CANCELLED: return "cancelled";
    case PN_ERROR_INTERNAL: return "internal error";
    }
    return "unknown status";
}

const char *pn_version_string(void) {
    return PN_VERSION_STRING;
}
