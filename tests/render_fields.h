/* render_fields.h — white-box access for the tests to the fields of a render's statistics (the
 * library's internal struct, render/stats.h). Tests that check a method's own counters read
 * them as fields; the public interface reads them by name (pn_stats_get, tests/test_stats.c). */
#ifndef PN_TESTS_RENDER_FIELDS_H
#define PN_TESTS_RENDER_FIELDS_H

#include "render/stats.h"

#include <string.h>

/* pn_render, with the statistics' fields copied to *fields (may be NULL; zeros when the render
 * produced none). */
static inline pn_status pn_test_render(pn_context ctx, pn_scene scene, const pn_render_settings *settings,
                                       pn_image *out_image, pn_render_stats *fields) {
    if (fields) memset(fields, 0, sizeof *fields);
    pn_stats stats = fields ? pn_stats_new() : NULL;
    if (fields && !stats) return PN_ERROR_OUT_OF_MEMORY;
    pn_status st = pn_render(ctx, scene, settings, out_image, stats);
    if (fields) *fields = stats->fields;
    pn_stats_free(stats);
    return st;
}

#endif
