/* test_warn.c — the library's warning path (core/warn.h): kept text, log delivery, the cap. */
#include "harness.h"

#include "core/context.h"
#include "core/warn.h"

#include <string.h>

typedef struct log_record {
    int count;
    pn_log_level last_level;
    char last[256];
} log_record;

static void record_log(void *user, pn_log_level level, const char *message) {
    log_record *r = user;
    r->count++;
    r->last_level = level;
    snprintf(r->last, sizeof r->last, "%s", message);
}

/* A warning is kept verbatim in the list and sent once to the log at warning level. */
static void test_warn_list_and_log(void) {
    pn_context ctx = pn_context_new();
    CHECK(ctx != NULL);
    if (!ctx) return;
    log_record r = {0};
    pn_context_set_log(ctx, record_log, &r);
    pn_warning_list list = {0};
    pn_warn(ctx, &list, "%s:%d:%d: %s", "a.pbrt", 12, 7, "something odd");
    pn_warn(ctx, &list, "light %d dropped", 3);
    CHECK(list.count == 2);
    CHECK(list.count == 2 && strcmp(list.items[0], "a.pbrt:12:7: something odd") == 0);
    CHECK(list.count == 2 && strcmp(list.items[1], "light 3 dropped") == 0);
    CHECK(r.count == 2);
    CHECK(r.last_level == PN_LOG_WARNING);
    CHECK(strcmp(r.last, "light 3 dropped") == 0);
    pn_warning_list_free(&list);
    CHECK(list.count == 0 && list.items == NULL);

    /* Without a list (not loading a scene) the warning only goes to the log. */
    pn_warn(ctx, NULL, "only logged %u", 5u);
    CHECK(r.count == 3);
    CHECK(strcmp(r.last, "only logged 5") == 0);
    /* Without a context it is only kept. */
    pn_warn(NULL, &list, "kept only");
    CHECK(list.count == 1 && strcmp(list.items[0], "kept only") == 0);
    CHECK(r.count == 3);
    pn_warning_list_free(&list);
    pn_context_free(ctx);
}

/* After PN_MAX_WARNINGS kept warnings, one "more than" line is kept and logged, then nothing. */
static void test_warn_cap(void) {
    pn_context ctx = pn_context_new();
    CHECK(ctx != NULL);
    if (!ctx) return;
    log_record r = {0};
    pn_context_set_log(ctx, record_log, &r);
    pn_warning_list list = {0};
    for (int i = 0; i < PN_MAX_WARNINGS + 5; i++) pn_warn(ctx, &list, "w%d", i);
    CHECK(list.count == PN_MAX_WARNINGS + 1);
    CHECK(r.count == PN_MAX_WARNINGS + 1);
    CHECK(strcmp(list.items[PN_MAX_WARNINGS - 1], "w9999") == 0);
    CHECK(strcmp(list.items[PN_MAX_WARNINGS], "more than 10000 warnings; the rest are not reported") == 0);
    CHECK(strcmp(r.last, "more than 10000 warnings; the rest are not reported") == 0);
    pn_warning_list_free(&list);
    pn_context_free(ctx);
}

PN_TESTS(TEST(test_warn_list_and_log), TEST(test_warn_cap))
