/* test_registry.c — the method table (integrators/registry.c) and what is generated from it.
 *
 * Library level: every entry is complete and findable; every declared option's type, range and
 * default are enforced by pn_options_set; an option is accepted by pn_options_check exactly for
 * the methods it applies to; with no options the job holds the defaults penumbra had before the
 * table (the documented values), and a set value reaches its job field.
 * CLI level (the built binary): `penumbra methods` lists every method and option; for every
 * method, every option of every other method is refused with exit 2 and a message naming the
 * method; bad values exit 2; `render --integrator X --help` shows X's options only; and the
 * statistics JSON reproduces its run: the options read back from it render the identical image;
 * its `stats` are exactly the declared statistics of its methods, in the table's order.
 */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif
#include "harness.h"

#include "integrators/registry.h"

#include <cjson/cJSON.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#ifndef PN_CLI_PATH
#error "PN_CLI_PATH must name the penumbra binary"
#endif

static char tmpdir[256];

/* ---- library level --------------------------------------------------------------------- */

static void test_table_entries(void) {
    int integrators = 0, drivers = 0;
    CHECK(pn_method_count() >= 12);
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        CHECK(mi && mi->name[0] && mi->description[0] && mi->computes[0] && mi->stats);
        CHECK(pn_method_find(mi->role, mi->name) == m);
        CHECK(pn_method_find_kind(mi->role, mi->kind) == m);
        if (mi->role == PN_METHOD_INTEGRATOR) {
            integrators++;
            CHECK(pn_integrator_find((pn_integrator_kind)mi->kind) == pn_registry_method(m)->integrator);
            CHECK(pn_registry_method(m)->integrator != NULL);
            CHECK(pn_registry_integrator_entry(pn_registry_method(m)->integrator) == pn_registry_method(m));
            /* capabilities say how it works: one of per pixel, per block, whole image */
            CHECK((mi->capabilities & (PN_CAP_PER_PIXEL | PN_CAP_PER_BLOCK | PN_CAP_WHOLE_IMAGE)) != 0);
            CHECK(((mi->capabilities & PN_CAP_WHOLE_IMAGE) != 0) ==
                  (pn_registry_method(m)->integrator->render_image != NULL));
            CHECK(!(mi->capabilities & PN_CAP_SPP) || mi->default_spp > 0 || (mi->capabilities & PN_CAP_THRESHOLD));
        } else {
            drivers++;
            CHECK(pn_registry_method(m)->integrator == NULL);
        }
    }
    CHECK(integrators == 7 && drivers == 5);
    CHECK(pn_method_find(PN_METHOD_INTEGRATOR, "tiles") == -1 && pn_method_find(PN_METHOD_DRIVER, "ias") == -1);
    CHECK(pn_method_get(-1) == NULL && pn_method_get(pn_method_count()) == NULL);
    CHECK(pn_method_find_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_DEFAULT) ==
          pn_method_find(PN_METHOD_INTEGRATOR, "reference"));
    /* every option applies to at least one method and is found by its name */
    for (int i = 0; i < pn_option_count(); i++) {
        int n = 0;
        for (int m = 0; m < pn_method_count(); m++) n += pn_option_applies(i, m);
        CHECK_MSG(n > 0, "%s applies to nothing", pn_option_get(i)->name);
        CHECK(pn_option_find(pn_option_get(i)->name) == i);
        CHECK(pn_option_get(i)->help[0]);
    }
}

static int set_ok(pn_options o, int i, const char *value) {
    pn_context ctx = pn_context_new();
    pn_status st = pn_options_set(ctx, o, pn_option_get(i)->name, value);
    if (st != PN_OK) {
        /* a refusal names the option and says what it accepts */
        const char *msg = pn_context_error_message(ctx);
        char expected[512];
        pn_option_describe(i, expected, sizeof expected);
        CHECK_STR_CONTAINS(msg, pn_option_get(i)->name);
        CHECK_STR_CONTAINS(msg, expected);
    }
    pn_context_free(ctx);
    return st == PN_OK;
}

/* Type, range and default of every declared option, through pn_options_set / _get. */
static void test_option_types_ranges_defaults(void) {
    pn_options o = pn_options_new();
    CHECK(o != NULL);
    char text[256];
    for (int i = 0; o && i < pn_option_count(); i++) {
        const pn_option_info *info = pn_option_get(i);
        double def = 0.0;
        CHECK(pn_options_get(o, i, &def, text, sizeof text) == PN_OK);
        CHECK(!pn_options_is_set(o, i));
        switch (info->type) {
        case PN_OPTION_INT: {
            CHECK(strtod(info->default_value, NULL) == def);
            char v[64];
            snprintf(v, sizeof v, "%.0f", info->min);
            CHECK(set_ok(o, i, v));
            CHECK(pn_options_get(o, i, &def, NULL, 0) == PN_OK && def == info->min);
            snprintf(v, sizeof v, "%.0f", info->max);
            CHECK(set_ok(o, i, v));
            snprintf(v, sizeof v, "%.0f", info->min - 1);
            CHECK(!set_ok(o, i, v));
            snprintf(v, sizeof v, "%.0f", info->max + 1);
            CHECK(!set_ok(o, i, v));
            CHECK(!set_ok(o, i, "1.5") && !set_ok(o, i, "abc") && !set_ok(o, i, "") && !set_ok(o, i, " 3") &&
                  !set_ok(o, i, "+3") && !set_ok(o, i, "3x"));
            break;
        }
        case PN_OPTION_DOUBLE: {
            CHECK(strtod(info->default_value, NULL) == def);
            char v[64];
            snprintf(v, sizeof v, "%.17g", info->min);
            CHECK(set_ok(o, i, v) == !info->min_exclusive);
            snprintf(v, sizeof v, "%.17g", info->min - 1e-3);
            CHECK(!set_ok(o, i, v));
            if (isfinite(info->max)) {
                snprintf(v, sizeof v, "%.17g", info->max);
                CHECK(set_ok(o, i, v) == !info->max_exclusive);
                snprintf(v, sizeof v, "%.17g", info->max + 1e-3);
                CHECK(!set_ok(o, i, v));
            }
            snprintf(v, sizeof v, "%.17g", isfinite(info->max) ? 0.5 * (info->min + info->max) : info->min + 0.5);
            CHECK(set_ok(o, i, v));
            CHECK(pn_options_get(o, i, &def, NULL, 0) == PN_OK && def == strtod(v, NULL));
            CHECK(!set_ok(o, i, "nan") && !set_ok(o, i, "inf") && !set_ok(o, i, "abc") && !set_ok(o, i, ""));
            break;
        }
        case PN_OPTION_FLAG:
            CHECK(def == 0.0);
            CHECK(set_ok(o, i, "1") && set_ok(o, i, "0") && set_ok(o, i, "true") && !set_ok(o, i, "2") &&
                  !set_ok(o, i, "yes please"));
            break;
        case PN_OPTION_CHOICE:
        case PN_OPTION_SET: {
            char name[64];
            const char *p = info->choices;
            int k = 0;
            CHECK(strlen(text) == 0 ? info->type == PN_OPTION_SET : strstr(info->choices, text) != NULL);
            while (*p) {
                size_t n = strcspn(p, ",");
                snprintf(name, sizeof name, "%.*s", (int)n, p);
                CHECK_MSG(set_ok(o, i, name), "%s %s", info->name, name);
                CHECK(pn_options_get(o, i, NULL, text, sizeof text) == PN_OK && strcmp(text, name) == 0);
                p += n;
                if (*p == ',') p++;
                k++;
            }
            CHECK(k >= 2);
            CHECK(!set_ok(o, i, "bogus"));
            if (info->type == PN_OPTION_SET) {
                CHECK(set_ok(o, i, ""));
                snprintf(text, sizeof text, "%s", info->choices);
                CHECK(set_ok(o, i, text)); /* all of them */
                /* an unknown name, and a known one with a trailing comma, are refused */
                char first[64];
                snprintf(first, sizeof first, "%.*s,", (int)strcspn(info->choices, ","), info->choices);
                CHECK(!set_ok(o, i, "bogus,x") && !set_ok(o, i, first));
            }
            break;
        }
        case PN_OPTION_LIST: {
            char v[128];
            snprintf(v, sizeof v, "%.17g,%.17g", info->max, 0.5 * (info->min + info->max));
            CHECK(set_ok(o, i, v));
            snprintf(v, sizeof v, "%.17g", info->max + 1);
            CHECK(!set_ok(o, i, v));
            CHECK(!set_ok(o, i, "1,,2") && !set_ok(o, i, "1,") && !set_ok(o, i, "a"));
            break;
        }
        case PN_OPTION_STRING: CHECK(set_ok(o, i, "any text")); break;
        }
        pn_options_unset(o, info->name);
        CHECK(!pn_options_is_set(o, i));
    }
    /* unknown names are refused with the list of what exists */
    pn_context ctx = pn_context_new();
    CHECK(pn_options_set(ctx, o, "no-such-option", "1") == PN_ERROR_INVALID_ARGUMENT);
    CHECK_STR_CONTAINS(pn_context_error_message(ctx), "vpls");
    pn_context_clear_error(ctx);
    CHECK(pn_options_set_double(ctx, o, "light-sampler", 1.0) == PN_ERROR_INVALID_ARGUMENT);
    pn_context_free(ctx);
    pn_options_free(o);
    pn_options_free(NULL);
}

/* A value of option i inside its range, as the CLI takes it (NULL for a flag). */
static const char *valid_value(int i, char *buf, size_t size) {
    const pn_option_info *info = pn_option_get(i);
    switch (info->type) {
    case PN_OPTION_FLAG: return NULL;
    case PN_OPTION_CHOICE:
    case PN_OPTION_SET: snprintf(buf, size, "%.*s", (int)strcspn(info->choices, ","), info->choices); break;
    case PN_OPTION_STRING: snprintf(buf, size, "trace.txt"); break;
    case PN_OPTION_INT: snprintf(buf, size, "%.0f", info->min); break;
    default: snprintf(buf, size, "%.17g", isfinite(info->max) ? 0.5 * (info->min + info->max) : info->min + 1); break;
    }
    return buf;
}

/* An option is accepted exactly by the methods it applies to; the refusal names the method. */
static void test_options_apply_per_table(void) {
    pn_context ctx = pn_context_new();
    for (int i = 0; i < pn_option_count(); i++) {
        for (int mi = 0; mi < pn_method_count(); mi++) {
            if (pn_method_get(mi)->role != PN_METHOD_INTEGRATOR) continue;
            for (int md = 0; md < pn_method_count(); md++) {
                if (pn_method_get(md)->role != PN_METHOD_DRIVER) continue;
                pn_options o = pn_options_new();
                char text[256];
                const char *v = valid_value(i, text, sizeof text);
                CHECK(pn_options_set(NULL, o, pn_option_get(i)->name, v ? v : "1") == PN_OK);
                pn_context_clear_error(ctx);
                pn_status st = pn_options_check(ctx, o, (pn_integrator_kind)pn_method_get(mi)->kind,
                                                (pn_driver_kind)pn_method_get(md)->kind);
                int applies = pn_option_applies(i, mi) || pn_option_applies(i, md);
                CHECK_MSG((st == PN_OK) == applies, "%s with %s/%s", pn_option_get(i)->name, pn_method_get(mi)->name,
                          pn_method_get(md)->name);
                if (!applies) {
                    CHECK_STR_CONTAINS(pn_context_error_message(ctx), pn_method_get(mi)->name);
                    CHECK_STR_CONTAINS(pn_context_error_message(ctx), pn_option_get(i)->name);
                }
                pn_options_free(o);
            }
        }
    }
    pn_context_free(ctx);
}

/* With no options the job holds penumbra's documented defaults (the values resolve_settings
 * applied before the table), and set values reach their fields. */
static void test_defaults_resolve_into_job(void) {
    pn_render_settings s = {0};
    pn_render_job job;
    memset(&job, 0xff, sizeof job);
    const pn_method_entry *ref = pn_registry_method_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_DEFAULT);
    const pn_method_entry *tiles = pn_registry_method_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT);
    CHECK(pn_registry_resolve(NULL, &s, ref, tiles, &job) == PN_OK);
    CHECK(job.shadow_rays == 4 && job.max_shadow_rays == 20000 && job.min_shadow_rays_black == 2500 &&
          job.min_eye_rays == 4);
    CHECK(job.cluster_solid_angle == 0.02f && job.aa_rays == 32 && job.env_regions == 300 && job.max_passes == 15);
    CHECK(job.block_size == 8 && job.light_sampler == PN_LIGHT_SAMPLER_IRRADIANCE);
    CHECK(job.vpls == 600000 && job.vpl_max_depth == 10 && job.vpl_clamp_fraction == 0.05f &&
          job.error_bound == 0.01f && job.max_cut == 0 && !job.visibility_sampling);
    CHECK(job.contour_grid == 3 && job.contour_steps == 5 && job.contour_span == 8 && job.contour_flags == 0);
    CHECK(job.contour_mc_threshold == 0.002 && job.contour_mc_max_rays == 256);
    CHECK(job.contour_scout == -1 && job.contour_part == 2 && job.contour_linear_tol == 0.003 &&
          job.contour_trace == NULL);
    CHECK(job.work_scale == 3 && job.primary_grid == 3 && job.stop_percent == 0.0 &&
          job.snapshot_every_seconds == 0.0 && !job.raw_radiance && !job.no_light_guide && job.snapshots.count == 0);

    pn_options o = pn_options_new();
    s.options = o;
    const pn_method_entry *lc = pn_registry_method_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_LIGHTCUTS);
    const pn_method_entry *dcm = pn_registry_method_kind(PN_METHOD_DRIVER, PN_DRIVER_DCM);
    CHECK(pn_options_set(NULL, o, "vpls", "1234") == PN_OK && pn_options_set(NULL, o, "error", "0.015") == PN_OK &&
          pn_options_set(NULL, o, "snapshots", "6,12.5") == PN_OK &&
          pn_options_set(NULL, o, "raw-radiance", "1") == PN_OK);
    CHECK(pn_registry_resolve(NULL, &s, lc, dcm, &job) == PN_OK);
    CHECK(job.vpls == 1234 && job.error_bound == 0.015f && job.raw_radiance);
    CHECK(job.snapshots.count == 2 && job.snapshots.values[0] == 6.0 && job.snapshots.values[1] == 12.5);
    /* not under the tiled driver, not for reference */
    CHECK(pn_registry_resolve(NULL, &s, lc, tiles, &job) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(pn_registry_resolve(NULL, &s, ref, dcm, &job) == PN_ERROR_INVALID_ARGUMENT);
    /* spp and threshold only where the integrator takes them */
    pn_options_free(o);
    s.options = NULL;
    s.spp = 4;
    const pn_method_entry *ias = pn_registry_method_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_IAS);
    CHECK(pn_registry_resolve(NULL, &s, ias, tiles, &job) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(pn_registry_resolve(NULL, &s, lc, tiles, &job) == PN_OK);
    s.spp = 0;
    s.threshold = 0.02;
    CHECK(pn_registry_resolve(NULL, &s, lc, tiles, &job) == PN_ERROR_INVALID_ARGUMENT);
    CHECK(pn_registry_resolve(NULL, &s, ias, tiles, &job) == PN_OK);
}

/* ---- CLI level ------------------------------------------------------------------------- */

/* Runs the CLI with args (NULL-terminated); stdout and stderr go to files in tmpdir, read into
 * out/err (malloc'ed, may be NULL). Returns the exit status. */
static char *slurp(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    if (s && fread(s, 1, (size_t)n, f) != (size_t)n) n = 0;
    if (s) s[n] = '\0';
    fclose(f);
    return s;
}

/* Room for a command line of the tests (args_from_json's: ias has the most options, two
 * arguments each). */
#define JSON_ARGS_MAX 160

static int run_cli(char **out, char **err, const char *const *args) {
    char out_path[300], err_path[300];
    snprintf(out_path, sizeof out_path, "%s/out.txt", tmpdir);
    snprintf(err_path, sizeof err_path, "%s/err.txt", tmpdir);
    const char *argv[JSON_ARGS_MAX + 8];
    int n = 0;
    argv[n++] = PN_CLI_PATH;
    while (args[n - 1]) {
        if (n >= JSON_ARGS_MAX + 7) {
            CHECK_MSG(false, "run_cli: more than %d arguments", JSON_ARGS_MAX + 6);
            return -1;
        }
        argv[n] = args[n - 1];
        n++;
    }
    argv[n] = NULL;
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        if (chdir(tmpdir) != 0) _exit(99);
        int fo = open(out_path, O_WRONLY | O_CREAT | O_TRUNC, 0644),
            fe = open(err_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fo < 0 || fe < 0) _exit(98);
        dup2(fo, 1);
        dup2(fe, 2);
        execv(PN_CLI_PATH, (char *const *)argv);
        _exit(97);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    if (out) *out = slurp(out_path);
    if (err) *err = slurp(err_path);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static void test_methods_command_lists_the_table(void) {
    char *out = NULL;
    CHECK(run_cli(&out, NULL, (const char *[]){"methods", NULL}) == 0);
    for (int m = 0; m < pn_method_count(); m++) {
        char line[128];
        snprintf(line, sizeof line, "\n%s (%s)", pn_method_get(m)->name,
                 pn_method_get(m)->role == PN_METHOD_DRIVER ? "driver" : "integrator");
        CHECK_STR_CONTAINS(out, line);
    }
    for (int i = 0; i < pn_option_count(); i++) {
        char flag[96];
        snprintf(flag, sizeof flag, "--%s", pn_option_get(i)->name);
        CHECK_STR_CONTAINS(out, flag);
    }
    free(out);
    CHECK(run_cli(NULL, NULL, (const char *[]){"methods", "no-such", NULL}) == 2);
}

/* For every method, every option of every other method: exit 2 and a message naming it. */
static void test_cli_refuses_other_methods_options(void) {
    int refused = 0;
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        int is_driver = mi->role == PN_METHOD_DRIVER;
        /* the other role: the default (tiles / reference) */
        int other = pn_method_find_kind(is_driver ? PN_METHOD_INTEGRATOR : PN_METHOD_DRIVER, 0);
        for (int i = 0; i < pn_option_count(); i++) {
            if (pn_option_applies(i, m) || pn_option_applies(i, other)) continue;
            char flag[96], value[128];
            snprintf(flag, sizeof flag, "--%s", pn_option_get(i)->name);
            const char *v = valid_value(i, value, sizeof value);
            const char *args[8] = {"render", "x.pbrt", is_driver ? "--driver" : "--integrator", mi->name, flag,
                                   v,        NULL};
            char *err = NULL;
            int code = run_cli(NULL, &err, args);
            CHECK_MSG(code == 2, "%s %s: exit %d", mi->name, flag, code);
            char expect[160];
            const pn_method_info *integ = pn_method_get(is_driver ? other : m),
                                 *drv = pn_method_get(is_driver ? m : other);
            snprintf(expect, sizeof expect, "%s does not apply to %s under the %s driver", flag, integ->name,
                     drv->name);
            CHECK_STR_CONTAINS(err, expect);
            free(err);
            refused++;
        }
        if (!is_driver) {
            /* spp and threshold, where the integrator does not take them */
            const char *which[2][2] = {{"--spp", "4"}, {"--threshold", "0.05"}};
            for (int k = 0; k < 2; k++) {
                uint32_t cap = k ? PN_CAP_THRESHOLD : PN_CAP_SPP;
                if (mi->capabilities & cap) continue;
                char *err = NULL;
                CHECK(run_cli(NULL, &err,
                              (const char *[]){"render", "x.pbrt", "--integrator", mi->name, which[k][0], which[k][1],
                                               NULL}) == 2);
                CHECK_STR_CONTAINS(err, mi->name);
                free(err);
            }
        }
    }
    CHECK(refused > 100);
}

/* Bad values of every option: exit 2, naming the flag. */
static void test_cli_enforces_declared_ranges(void) {
    for (int i = 0; i < pn_option_count(); i++) {
        const pn_option_info *info = pn_option_get(i);
        if (info->type == PN_OPTION_STRING) continue;
        int m = 0;
        while (!pn_option_applies(i, m)) m++;
        const pn_method_info *mi = pn_method_get(m);
        char flag[96], bad[64];
        snprintf(flag, sizeof flag, "--%s", info->name);
        if (info->type == PN_OPTION_INT || info->type == PN_OPTION_DOUBLE || info->type == PN_OPTION_LIST)
            snprintf(bad, sizeof bad, "%.17g", info->min - 1);
        else
            snprintf(bad, sizeof bad, "bogus");
        char arg[192];
        if (info->type == PN_OPTION_FLAG)
            snprintf(arg, sizeof arg, "%s=2", flag);
        else
            snprintf(arg, sizeof arg, "%s=%s", flag, bad);
        char *err = NULL;
        const char *args[] = {"render", "x.pbrt", mi->role == PN_METHOD_DRIVER ? "--driver" : "--integrator",
                              mi->name, arg,      NULL};
        CHECK_MSG(run_cli(NULL, &err, args) == 2, "%s", arg);
        CHECK_STR_CONTAINS(err, flag);
        free(err);
    }
}

static void test_cli_help_per_method(void) {
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        if (mi->role != PN_METHOD_INTEGRATOR) continue;
        char *out = NULL;
        CHECK(run_cli(&out, NULL, (const char *[]){"render", "--integrator", mi->name, "--help", NULL}) == 0);
        int tiles = pn_method_find_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT);
        for (int i = 0; i < pn_option_count(); i++) {
            char flag[96];
            snprintf(flag, sizeof flag, "  --%s ", pn_option_get(i)->name);
            int shown = out && strstr(out, flag) != NULL;
            if (pn_option_get(i)->type == PN_OPTION_FLAG) continue; /* flags have no " VALUE" */
            CHECK_MSG(shown == (pn_option_applies(i, m) || pn_option_applies(i, tiles)), "%s in %s's help",
                      pn_option_get(i)->name, mi->name);
        }
        char head[96];
        snprintf(head, sizeof head, "\n%s (integrator): ", mi->name);
        CHECK_STR_CONTAINS(out, head);
        free(out);
    }
}

/* A small scene with a rectangle light (contour's), a point light and an occluder. */
static const char *scene_text =
    "LookAt 0 3 4  0 0 0  0 1 0\n"
    "Camera \"perspective\" \"float fov\" [ 45 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 16 ]\n"
    "WorldBegin\n"
    "LightSource \"point\" \"point3 from\" [ 1 2 1 ] \"rgb I\" [ 2 2 2 ]\n"
    "AttributeBegin\n"
    "  AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ]\n"
    "  Shape \"trianglemesh\" \"point3 P\" [ -0.5 2 -0.5  0.5 2 -0.5  0.5 2 0.5  -0.5 2 0.5 ]\n"
    "    \"integer indices\" [ 0 2 1  0 3 2 ]\n"
    "AttributeEnd\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.6 0.6 0.6 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -5 0 -5  5 0 -5  5 0 5  -5 0 5 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "Shape \"sphere\" \"float radius\" [ 0.4 ]\n";

/* Builds render arguments from a stats JSON: the settings and every option it records. */
static int args_from_json(const char *json, const char *scene, const char *output, char store[][128],
                          const char **args) {
    cJSON *root = cJSON_Parse(json);
    int n = 0;
    if (!root) return -1;
    const cJSON *set = cJSON_GetObjectItemCaseSensitive(root, "settings");
    CHECK(cJSON_GetObjectItemCaseSensitive(root, "schema_version") != NULL);
#define ADD(text)                                                                                                      \
    do {                                                                                                               \
        if (n >= JSON_ARGS_MAX) {                                                                                      \
            CHECK_MSG(false, "more than %d arguments from the JSON", JSON_ARGS_MAX);                                   \
            break;                                                                                                     \
        }                                                                                                              \
        snprintf(store[n], 128, "%s", (text));                                                                         \
        args[n] = store[n];                                                                                            \
        n++;                                                                                                           \
    } while (0)
    ADD("render");
    ADD(scene);
    ADD("-o");
    ADD(output);
    ADD("--quiet");
    ADD("--integrator");
    ADD(cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(set, "integrator")));
    ADD("--driver");
    ADD(cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(set, "driver")));
    char v[128];
    const cJSON *spp = cJSON_GetObjectItemCaseSensitive(set, "spp");
    const cJSON *thr = cJSON_GetObjectItemCaseSensitive(set, "threshold");
    if (cJSON_IsNumber(spp)) {
        ADD("--spp");
        snprintf(v, sizeof v, "%.0f", spp->valuedouble);
        ADD(v);
    } else if (cJSON_IsNumber(thr)) {
        ADD("--threshold");
        snprintf(v, sizeof v, "%.17g", thr->valuedouble);
        ADD(v);
    }
    const cJSON *res = cJSON_GetObjectItemCaseSensitive(set, "resolution");
    if (cJSON_IsArray(res)) {
        ADD("--resolution");
        snprintf(v, sizeof v, "%.0fx%.0f", cJSON_GetArrayItem(res, 0)->valuedouble,
                 cJSON_GetArrayItem(res, 1)->valuedouble);
        ADD(v);
    }
    const cJSON *crop = cJSON_GetObjectItemCaseSensitive(set, "crop");
    if (cJSON_IsArray(crop)) {
        ADD("--crop");
        snprintf(v, sizeof v, "%.17g,%.17g,%.17g,%.17g", cJSON_GetArrayItem(crop, 0)->valuedouble,
                 cJSON_GetArrayItem(crop, 1)->valuedouble, cJSON_GetArrayItem(crop, 2)->valuedouble,
                 cJSON_GetArrayItem(crop, 3)->valuedouble);
        ADD(v);
    }
    ADD("--seed");
    ADD(cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(set, "seed")));
    const cJSON *opt;
    int options = 0;
    cJSON_ArrayForEach(opt, cJSON_GetObjectItemCaseSensitive(set, "options")) {
        char flag[96];
        snprintf(flag, sizeof flag, "--%s", opt->string);
        options++;
        if (cJSON_IsBool(opt)) {
            if (cJSON_IsTrue(opt)) ADD(flag);
            continue;
        }
        if (cJSON_IsString(opt) && opt->valuestring[0] == '\0') continue; /* "": none */
        if (cJSON_IsNumber(opt))
            snprintf(v, sizeof v, "%.17g", opt->valuedouble);
        else
            snprintf(v, sizeof v, "%s", opt->valuestring);
        /* an option at a default outside its range ("none", e.g. max-cut 0) is left out */
        const pn_option_info *info = pn_option_get(pn_option_find(opt->string));
        if (cJSON_IsNumber(opt) &&
            (opt->valuedouble < info->min || (info->min_exclusive && opt->valuedouble == info->min)))
            continue;
        ADD(flag);
        ADD(v);
    }
#undef ADD
    args[n] = NULL;
    cJSON_Delete(root);
    return options;
}

static int same_file(const char *a, const char *b) {
    char *x = slurp(a), *y = slurp(b);
    struct stat sa, sb;
    int same = x && y && stat(a, &sa) == 0 && stat(b, &sb) == 0 && sa.st_size == sb.st_size &&
               memcmp(x, y, (size_t)sa.st_size) == 0;
    free(x);
    free(y);
    return same;
}

/* Render, read the options back from the JSON, render again with them: the identical image. */
/* The JSON's `stats` are the declared statistics (render/stats.c) that its integrator and driver
 * produce, in the table's order, and nothing else (the per-rank arrays need several ranks). */
static void check_json_stats(const char *json, size_t c) {
    cJSON *root = cJSON_Parse(json);
    const cJSON *set = cJSON_GetObjectItemCaseSensitive(root, "settings");
    int mi =
        pn_method_find(PN_METHOD_INTEGRATOR, cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(set, "integrator")));
    int md = pn_method_find(PN_METHOD_DRIVER, cJSON_GetStringValue(cJSON_GetObjectItemCaseSensitive(set, "driver")));
    const cJSON *stats = cJSON_GetObjectItemCaseSensitive(root, "stats");
    CHECK(mi >= 0 && md >= 0 && cJSON_IsObject(stats));
    const cJSON *item = stats ? stats->child : NULL;
    for (int i = 0; i < pn_stat_count(); i++) {
        const pn_stat_info *si = pn_stat_get(i);
        if (si->per_rank || (!pn_stat_applies(i, mi) && !pn_stat_applies(i, md))) continue;
        CHECK_MSG(item && strcmp(item->string, si->name) == 0, "case %zu: '%s' expected, the JSON has '%s'", c,
                  si->name, item ? item->string : "nothing");
        CHECK_MSG(item && (si->type == PN_STAT_FLAG ? cJSON_IsBool(item) : cJSON_IsNumber(item)), "case %zu: '%s'", c,
                  si->name);
        if (item) item = item->next;
    }
    CHECK_MSG(item == NULL, "case %zu: '%s' in the JSON's stats is not declared for its methods", c,
              item ? item->string : "");
    cJSON_Delete(root);
}

static void test_json_round_trip(void) {
    pn_test_write_file(tmpdir, "rt.pbrt", scene_text);
    const char *cases[][12] = {
        {"--spp", "3", "--light-sampler", "bvh", "--shadow-rays", "2", "--seed", "5", NULL},
        {"--integrator", "ias", "--threshold", "0.05", "--cluster-solid-angle", "0.03", "--block-size", "16", NULL},
        {"--integrator", "lightcuts", "--vpls", "500", "--error", "0.02", "--vpl-depth", "3", "--crop", "0.1,0.9,0,1",
         NULL},
        {"--integrator", "illumcut", "--vpls", "400", "--visibility", "sampling", "--vpl-clamp", "0.07", NULL},
        {"--integrator", "contour", "--contour-off", "spans,scouts", "--contour-grid", "4", "--spp", "2", NULL},
        {"--integrator", "contour-mc", "--mc-threshold", "0.01", "--mc-max-rays", "64", NULL},
        {"--driver", "dcm", "--spp", "2", "--stop-at", "40", "--work-scale", "2", "--raw-radiance", NULL},
    };
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        const char *args[40] = {"render", "rt.pbrt", "-o", "a.exr", "--stats", "a.json", "--quiet", "--threads", "2"};
        int n = 9;
        for (int k = 0; cases[c][k]; k++) args[n++] = cases[c][k];
        args[n] = NULL;
        char *err = NULL;
        int code = run_cli(NULL, &err, args);
        CHECK_MSG(code == 0, "case %zu: exit %d: %s", c, code, err ? err : "");
        free(err);
        char path[300];
        snprintf(path, sizeof path, "%s/a.json", tmpdir);
        char *json = slurp(path);
        CHECK(json != NULL);
        if (!json) continue;
        check_json_stats(json, c);
        char store[JSON_ARGS_MAX][128];
        const char *again[JSON_ARGS_MAX + 3];
        int options = args_from_json(json, "rt.pbrt", "b.exr", store, again);
        free(json);
        CHECK_MSG(options > 0, "case %zu: no options in the JSON", c);
        int k = 0;
        while (again[k]) k++;
        again[k++] = "--threads";
        again[k++] = "1"; /* the image does not depend on the thread count */
        again[k] = NULL;
        code = run_cli(NULL, &err, again);
        CHECK_MSG(code == 0, "case %zu again: exit %d: %s", c, code, err ? err : "");
        free(err);
        char a[300], b[300];
        snprintf(a, sizeof a, "%s/a.exr", tmpdir);
        snprintf(b, sizeof b, "%s/b.exr", tmpdir);
        CHECK_MSG(same_file(a, b), "case %zu: the JSON's options rendered a different image", c);
    }
}

static void setup(void) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_registry_XXXXXX");
    CHECK(mkdtemp(tmpdir) != NULL);
}

static void teardown(void) {
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    CHECK(system(cmd) == 0);
}

PN_TESTS(TEST(setup), TEST(test_table_entries), TEST(test_option_types_ranges_defaults),
         TEST(test_options_apply_per_table), TEST(test_defaults_resolve_into_job),
         TEST(test_methods_command_lists_the_table), TEST(test_cli_refuses_other_methods_options),
         TEST(test_cli_enforces_declared_ranges), TEST(test_cli_help_per_method), TEST(test_json_round_trip),
         TEST(teardown))
