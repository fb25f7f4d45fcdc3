/* warn.c — the warning path of warn.h: keep a copy in the list, then log through the context. */
#include "core/warn.h"
#include "core/context.h"
#include "core/text.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void pn_warnv(pn_context ctx, pn_warning_list *list, const char *fmt, va_list ap) {
    char raw[1024], buf[1024];
    if (list && list->count > PN_MAX_WARNINGS) return;
    if (list && list->count == PN_MAX_WARNINGS) {
        snprintf(buf, sizeof buf, "more than %d warnings; the rest are not reported", PN_MAX_WARNINGS);
    } else {
        vsnprintf(raw, sizeof raw, fmt, ap);
        pn_text_escape(buf, sizeof buf, raw); /* warnings quote file content (core/text.h) */
    }
    if (list) {
        /* The list grows in powers of two; its capacity follows from its count. */
        int n = list->count;
        if (n == 0 || (n >= 4 && (n & (n - 1)) == 0)) {
            size_t cap = n == 0 ? 4 : (size_t)n * 2;
            char **grown = realloc(list->items, cap * sizeof *grown);
            if (!grown) return;
            list->items = grown;
        }
        char *copy = strdup(buf);
        if (!copy) return;
        list->items[list->count++] = copy;
    }
    if (ctx) pn_context_log(ctx, PN_LOG_WARNING, "%s", buf);
}

void pn_warn(pn_context ctx, pn_warning_list *list, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    pn_warnv(ctx, list, fmt, ap);
    va_end(ap);
}

void pn_warning_list_free(pn_warning_list *list) {
    if (!list) return;
    for (int i = 0; i < list->count; i++) free(list->items[i]);
    free(list->items);
    list->items = NULL;
    list->count = 0;
}
