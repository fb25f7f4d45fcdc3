/* test_stats.c — the declared statistics table (render/stats.c) and the by-name interface over it.
 *
 * The table is complete and consistent with the method table: names unique and findable, every
 * group a statistic names is produced by some method and every group a method names has
 * statistics; the fields it declares cover pn_render_stats (white-box: the internal struct).
 * Per method (every integrator under the tiled driver, every driver with the reference
 * integrator) a tiny render shows that what the render reports is what the table declares and
 * vice versa: pn_stats_get answers exactly for the statistics the table says the methods
 * produce; every byte the render wrote into the struct lies in a declared field of a produced
 * statistic; each group the methods name has a non-zero statistic. Unknown names, per-rank
 * names and unfilled handles answer "not produced". The settings' struct_size guard. */
#include "harness.h"
#include "render_fields.h"

#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[256];

static const char *scene_text =
    "LookAt 0 3 4  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 45 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"point3 from\" [ 1 2 1 ] \"rgb I\" [ 2 2 2 ]\n"
    "AttributeBegin\n"
    "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
    "  Shape \"trianglemesh\" \"point3 P\" [ -0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5 ]\n"
    "    \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "AttributeEnd\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -5 0 -5  5 0 -5  5 0 5  -5 0 5 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"sphere\" \"float radius\" [ 0.4 ]\n";

/* Bytes of the field that holds declared statistic d (0 for a ratio, which owns no field). */
static size_t field_size(const pn_stat_decl *d) {
    switch (d->field) {
    case PN_STAT_F64:
    case PN_STAT_U64: return 8;
    case PN_STAT_U32:
    case PN_STAT_I32: return 4;
    case PN_STAT_RATIO: return 0;
    case PN_STAT_F64_RANKS: return 8 * PN_STATS_MAX_RANKS;
    case PN_STAT_U32_RANKS: return 4 * PN_STATS_MAX_RANKS;
    }
    return 0;
}

/* The declared statistic whose field holds byte `at` of pn_render_stats, or -1. */
static int stat_at(size_t at) {
    for (int i = 0; i < pn_stats_decl_count(); i++) {
        const pn_stat_decl *d = pn_stats_decl(i);
        if (at >= d->offset && at < d->offset + field_size(d)) return i;
    }
    return -1;
}

static void test_table_is_complete(void) {
    CHECK(pn_stat_count() == pn_stats_decl_count() && pn_stat_count() > 50);
    for (int i = 0; i < pn_stat_count(); i++) {
        const pn_stat_info *si = pn_stat_get(i);
        CHECK(si && si == &pn_stats_decl(i)->info);
        CHECK_MSG(si->name[0] && si->help[0] && si->unit && si->group, "entry %d", i);
        CHECK_MSG(pn_stat_find(si->name) == i, "'%s' is declared twice", si->name);
        CHECK((int)si->type >= PN_STAT_COUNT && (int)si->type <= PN_STAT_FLAG);
        CHECK((int)si->merge >= PN_STAT_MERGE_SUM && (int)si->merge <= PN_STAT_MERGE_FIRST);
        const pn_stat_decl *d = pn_stats_decl(i);
        bool array = d->field == PN_STAT_F64_RANKS || d->field == PN_STAT_U32_RANKS;
        CHECK_MSG(array == (si->per_rank != 0), "'%s': per_rank and its field disagree", si->name);
        CHECK_MSG(d->offset + (field_size(d) ? field_size(d) : 8) <= sizeof(pn_render_stats), "'%s'", si->name);
        if (si->type == PN_STAT_FLAG) CHECK(si->merge == PN_STAT_MERGE_ANY);
        if (si->type == PN_STAT_SECONDS) CHECK_MSG(strcmp(si->unit, "s") == 0, "'%s'", si->name);
        /* A group is produced by at least one method. */
        int producers = 0;
        for (int m = 0; m < pn_method_count(); m++) producers += pn_stat_applies(i, m);
        CHECK_MSG(producers > 0, "no method produces '%s' (group '%s')", si->name, si->group);
    }
    /* Every group a method names has statistics. */
    for (int m = 0; m < pn_method_count(); m++) {
        const char *groups = pn_method_get(m)->stats;
        for (const char *p = groups; *p;) {
            size_t len = strcspn(p, ",");
            char group[64];
            snprintf(group, sizeof group, "%.*s", (int)len, p);
            int found = 0;
            for (int i = 0; i < pn_stat_count(); i++) found += strcmp(pn_stat_get(i)->group, group) == 0;
            CHECK_MSG(found > 0, "%s names group '%s', which has no statistics", pn_method_get(m)->name, group);
            p += len;
            if (*p == ',') p++;
        }
    }
    CHECK(pn_stat_find("no_such_statistic") == -1 && pn_stat_find(NULL) == -1);
    CHECK(pn_stat_get(-1) == NULL && pn_stat_get(pn_stat_count()) == NULL);
    CHECK(!pn_stat_applies(-1, 0) && !pn_stat_applies(0, -1) && !pn_stat_applies(0, pn_method_count()));
}

/* The declared fields cover the struct: no field of 4 bytes or more is left out (a gap is at
 * most the padding before an 8-byte field), and no two overlap. */
static void test_fields_cover_the_struct(void) {
    size_t at = 0;
    while (at < sizeof(pn_render_stats)) {
        int i = stat_at(at);
        if (i >= 0) {
            const pn_stat_decl *d = pn_stats_decl(i);
            CHECK_MSG(d->offset == at, "'%s' overlaps another field", d->info.name);
            for (size_t b = at; b < at + field_size(d); b++) CHECK(stat_at(b) == i);
            at += field_size(d);
            continue;
        }
        size_t gap = at;
        while (at < sizeof(pn_render_stats) && stat_at(at) < 0) at++;
        CHECK_MSG(at - gap < 4 || (at - gap == 4 && at % 8 == 0 && gap % 8 == 4),
                  "bytes %zu..%zu of pn_render_stats are in no declared statistic", gap, at);
    }
}

/* Renders the tiny scene with integrator method mi under driver method md; checks the report. */
static void check_method(pn_scene scene, int mi, int md) {
    const pn_method_info *ii = pn_method_get(mi), *di = pn_method_get(md);
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, NULL, NULL);
    pn_options opts = pn_options_new();
    pn_render_settings s = PN_RENDER_SETTINGS_INIT;
    s.integrator = (pn_integrator_kind)ii->kind;
    s.driver = (pn_driver_kind)di->kind;
    s.threads = 2;
    s.seed = 3;
    if (ii->capabilities & PN_CAP_SPP) s.spp = 1;
    if (!(ii->capabilities & PN_CAP_SPP)) s.threshold = 0.1;
    if (strstr(ii->computes, "VPL")) pn_options_set(ctx, opts, "vpls", "200");
    s.options = opts;
    pn_stats stats = pn_stats_new();
    double v = -1.0;
    CHECK(!pn_stats_get(stats, "eye_rays", &v) && v == -1.0); /* nothing rendered yet */
    pn_image img = NULL;
    pn_status st = pn_render(ctx, scene, &s, &img, stats);
    CHECK_MSG(st == PN_OK, "%s/%s: %s", ii->name, di->name, pn_context_error_message(ctx));
    if (st == PN_OK) {
        /* pn_stats_get answers exactly for what the table says these methods produce. */
        for (int i = 0; i < pn_stat_count(); i++) {
            const pn_stat_info *si = pn_stat_get(i);
            int expected = (pn_stat_applies(i, mi) || pn_stat_applies(i, md)) && !si->per_rank;
            CHECK_MSG(pn_stats_get(stats, si->name, NULL) == expected, "%s/%s: '%s' %s", ii->name, di->name, si->name,
                      expected ? "missing" : "reported but not declared for these methods");
            if (si->per_rank) CHECK(pn_stats_get_array(stats, si->name, NULL, 0) == 0); /* one process */
        }
        /* Every byte the render wrote lies in a declared statistic of these methods. */
        const unsigned char *bytes = (const unsigned char *)&stats->fields;
        for (size_t b = 0; b < sizeof stats->fields; b++) {
            if (!bytes[b]) continue;
            int i = stat_at(b);
            CHECK_MSG(i >= 0, "%s/%s: byte %zu of pn_render_stats is set but in no declared statistic", ii->name,
                      di->name, b);
            if (i >= 0)
                CHECK_MSG(pn_stat_applies(i, mi) || pn_stat_applies(i, md), "%s/%s filled '%s', not declared for them",
                          ii->name, di->name, pn_stat_get(i)->name);
            if (i >= 0) b = pn_stats_decl(i)->offset + field_size(pn_stats_decl(i)) - 1;
        }
        /* Each group the methods name has a non-zero statistic in this render. */
        for (int m = 0; m < 2; m++) {
            const char *groups = pn_method_get(m ? md : mi)->stats;
            for (const char *p = groups; *p;) {
                size_t len = strcspn(p, ",");
                char group[64];
                snprintf(group, sizeof group, "%.*s", (int)len, p);
                int nonzero = 0;
                for (int i = 0; i < pn_stat_count(); i++)
                    if (strcmp(pn_stat_get(i)->group, group) == 0 && pn_stats_get(stats, pn_stat_get(i)->name, &v))
                        nonzero += v != 0.0;
                CHECK_MSG(nonzero > 0, "%s/%s: group '%s' all zero", ii->name, di->name, group);
                p += len;
                if (*p == ',') p++;
            }
        }
        CHECK(pn_stats_get(stats, "eye_rays", &v) && v > 0.0);
        CHECK(pn_stats_get(stats, "width", &v) && v == 16.0);
        CHECK(pn_stats_get(stats, "ranks", &v) && v == 1.0);
        v = -1.0;
        CHECK(!pn_stats_get(stats, "no_such_statistic", &v) && v == -1.0);
        CHECK(!pn_stats_get(stats, "rank_tiles", &v) && v == -1.0); /* per rank: the array call */
        CHECK(!pn_stats_get_array(stats, "eye_rays", NULL, 0));     /* scalar */
    }
    pn_image_free(img);
    pn_stats_free(stats);
    pn_options_free(opts);
    pn_context_free(ctx);
}

static pn_scene load_scene(void) {
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, NULL, NULL);
    pn_scene scene = NULL;
    const char *path = pn_test_write_file(tmpdir, "tiny.pbrt", scene_text);
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    pn_context_free(ctx);
    return scene;
}

static void test_every_method_reports_what_it_declares(void) {
    pn_scene scene = load_scene();
    if (!scene) return;
    int reference = pn_method_find_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_REFERENCE);
    int tiles = pn_method_find_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT);
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *info = pn_method_get(m);
        if (info->role == PN_METHOD_INTEGRATOR)
            check_method(scene, m, tiles);
        else
            check_method(scene, reference, m);
    }
    pn_scene_free(scene);
}

/* pn_render_settings.struct_size: 0 and this size render; a larger caller's unknown fields must
 * be zero; a smaller size is refused. pn_stats of a refused render: nothing produced. */
static void test_settings_size_guard(void) {
    pn_scene scene = load_scene();
    if (!scene) return;
    pn_context ctx = pn_context_new();
    pn_context_set_log(ctx, NULL, NULL);
    struct {
        pn_render_settings s;
        uint64_t later_field;
    } newer;
    memset(&newer, 0, sizeof newer);
    newer.s.spp = 1;
    newer.s.threads = 1;
    pn_stats stats = pn_stats_new();
    pn_image img = NULL;
    pn_render_settings zero = newer.s, init;
    pn_render_settings_init(&init);
    CHECK(init.struct_size == sizeof init && init.spp == 0 && init.options == NULL);
    CHECK(pn_render(ctx, scene, &zero, &img, stats) == PN_OK && img);
    pn_image_free(img);
    newer.s.struct_size = (uint32_t)sizeof newer;
    CHECK(pn_render(ctx, scene, &newer.s, &img, stats) == PN_OK && img);
    pn_image_free(img);
    newer.later_field = 1;
    CHECK(pn_render(ctx, scene, &newer.s, &img, stats) == PN_ERROR_INVALID_ARGUMENT && !img);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "struct_size");
    CHECK(!pn_stats_get(stats, "eye_rays", NULL));
    pn_context_clear_error(ctx);
    zero.struct_size = 8;
    CHECK(pn_render(ctx, scene, &zero, &img, stats) == PN_ERROR_INVALID_ARGUMENT && !img);
    pn_context_clear_error(ctx);
    double lux = 0.0;
    pn_illuminance_point pt = {{2, 0.001f, 0}, {0, 1, 0}};
    CHECK(pn_illuminance(ctx, scene, &zero, &pt, 1, &lux) == PN_ERROR_INVALID_ARGUMENT);
    zero.struct_size = 0;
    CHECK(pn_illuminance(ctx, scene, &zero, &pt, 1, &lux) == PN_OK && lux > 0.0);
    pn_stats_free(stats);
    pn_context_free(ctx);
    pn_scene_free(scene);
}

static void setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_stats_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void teardown(void) {
    char path[300];
    snprintf(path, sizeof path, "%s/tiny.pbrt", tmpdir);
    unlink(path);
    CHECK(rmdir(tmpdir) == 0);
}

PN_TESTS(TEST(setup), TEST(test_table_is_complete), TEST(test_fields_cover_the_struct),
         TEST(test_every_method_reports_what_it_declares), TEST(test_settings_size_guard), TEST(teardown))
