/* error.h — the library's one error model: a status plus the message of the first failure. */
#ifndef PN_CORE_ERROR_H
#define PN_CORE_ERROR_H

#include "penumbra/penumbra.h"
#include <stdarg.h>

/* Keeps the first failure: later pn_err_set calls on an already failed pn_err are ignored, so
 * the message the user sees names the root cause, not a consequence. */
typedef struct pn_err {
    pn_status status;
    char message[1024];
} pn_err;

void pn_err_init(pn_err *err);
/* Records status and a printf-style message (if err has no failure yet) and returns status. */
pn_status pn_err_set(pn_err *err, pn_status status, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
pn_status pn_err_setv(pn_err *err, pn_status status, const char *fmt, va_list ap);

#endif
