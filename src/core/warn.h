/* warn.h — the library's one warning path: a warning is kept in a list (a scene's, while it is
 * being loaded) and sent to the context's log callback. The parser and the light builder both use
 * it, so neither lights/ nor any later stage needs scene-parser code to report a problem. */
#ifndef PN_CORE_WARN_H
#define PN_CORE_WARN_H

#include "core/error.h"

#include <stdarg.h>

/* Warnings kept for the caller to read back ("file:line:column: message" where there is a
 * source location). At most PN_MAX_WARNINGS are kept; the next one is replaced by a single
 * "more than ... warnings" line and the rest are dropped (and not logged). */
#define PN_MAX_WARNINGS 10000
typedef struct pn_warning_list {
    char **items;
    int count;
} pn_warning_list;

/* Formats the warning, appends a copy to `list` (when not NULL) and logs it at PN_LOG_WARNING
 * through `ctx` (when not NULL). With no list the message only goes to the log. */
void pn_warn(pn_context ctx, pn_warning_list *list, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
void pn_warnv(pn_context ctx, pn_warning_list *list, const char *fmt, va_list ap) __attribute__((format(printf, 3, 0)));

/* Frees the kept texts (the list is left empty). */
void pn_warning_list_free(pn_warning_list *list);

#endif
