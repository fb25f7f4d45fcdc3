/* options.c — `penumbra render`'s arguments, its --help and `penumbra methods`, all generated
 * from the library's method table (pn_method_*, pn_option_*): a flag --NAME is the option NAME
 * of the table, checked against its declared type and range, and refused (exit 2) when it does
 * not apply to the chosen integrator or driver. Only the options every method shares (output,
 * resolution, crop, threads, seed, spp/threshold, AOVs) are spelled out here. */
#include "cli/cli.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

static void appendf(char *buf, size_t size, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void appendf(char *buf, size_t size, const char *fmt, ...) {
    size_t len = strlen(buf);
    if (len + 1 >= size) return;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buf + len, size - len, fmt, ap);
    va_end(ap);
}

void format_aov_names(uint32_t bits, char *buf, size_t size) {
    buf[0] = '\0';
    int total = 0, seen = 0;
    uint32_t bit;
    for (int i = 0; pn_aov_name(i, &bit); i++) total += (bits & bit) != 0;
    for (int i = 0; pn_aov_name(i, &bit); i++) {
        if (!(bits & bit)) continue;
        seen++;
        appendf(buf, size, "%s%s", seen == 1 ? "" : seen == total ? " and " : ", ", pn_aov_name(i, NULL));
    }
}

static uint32_t all_aovs(void) {
    uint32_t all = 0, bit;
    for (int i = 0; pn_aov_name(i, &bit); i++) all |= bit;
    return all;
}

/* AOVs only drivers with PN_CAP_OWN_AOVS write. */
static uint32_t driver_own_aovs(void) {
    uint32_t bits = 0;
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        if (mi->role == PN_METHOD_DRIVER && (mi->capabilities & PN_CAP_OWN_AOVS)) bits |= mi->aovs;
    }
    return bits;
}

/* Comma list of AOV names or "all"; on failure bad receives the offending name. */
static int parse_aovs(const char *text, uint32_t *bits, char *bad, size_t bad_size) {
    if (strcmp(text, "all") == 0) {
        *bits = all_aovs();
        return 1;
    }
    uint32_t result = 0;
    const char *cursor = text;
    for (;;) {
        const char *comma = strchr(cursor, ',');
        size_t n = comma ? (size_t)(comma - cursor) : strlen(cursor);
        int found = 0;
        uint32_t bit;
        for (int i = 0; pn_aov_name(i, &bit); i++) {
            const char *name = pn_aov_name(i, NULL);
            if (strlen(name) == n && strncmp(name, cursor, n) == 0) {
                result |= bit;
                found = 1;
            }
        }
        if (!found) {
            snprintf(bad, bad_size, "%.*s", (int)n, cursor);
            return 0;
        }
        if (comma == NULL) break;
        cursor = comma + 1;
    }
    *bits = result;
    return 1;
}

/* "'reference' or 'ias' (or 'contour', ...)" for the methods of a role. */
static void method_names(pn_method_role role, char *buf, size_t size) {
    buf[0] = '\0';
    int n = 0;
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        if (mi->role != role) continue;
        appendf(buf, size, "%s'%s'", n == 0 ? "" : n == 1 ? " or " : n == 2 ? " (or " : ", ", mi->name);
        n++;
    }
    if (n > 2) appendf(buf, size, ")");
}

/* "--light-sampler, --shadow-rays, ..." for the options of method m ("no options"). */
static void option_flags(int m, char *buf, size_t size) {
    int n = 0;
    for (int i = 0; i < pn_option_count(); i++)
        if (pn_option_applies(i, m)) appendf(buf, size, "%s--%s", n++ ? ", " : "", pn_option_get(i)->name);
    if (n == 0) appendf(buf, size, "no options of its own");
}

/* The usage error for a flag that the chosen methods do not take; `where` lists the methods
 * (bit per method index) it applies to. */
static int not_applicable(const render_options *o, const char *flag, uint64_t where) {
    char list[512] = "", msg[2048] = "";
    int count = 0, roles = 0, seen = 0;
    for (int m = 0; m < pn_method_count(); m++)
        if (where & (1ull << m)) {
            count++;
            roles |= pn_method_get(m)->role == PN_METHOD_DRIVER ? 2 : 1;
        }
    for (int m = 0; m < pn_method_count(); m++)
        if (where & (1ull << m)) {
            seen++;
            appendf(list, sizeof list, "%s%s", seen == 1 ? "" : seen == count ? " and " : ", ", pn_method_get(m)->name);
        }
    const pn_method_info *mi = pn_method_get(o->integrator), *md = pn_method_get(o->driver);
    /* "--spp does not apply to ias under the tiles driver: it applies to the reference ... integrators" */
    appendf(msg, sizeof msg, "%s does not apply to %s under the %s driver: it applies to the %s %s%s", flag, mi->name,
            md->name, list,
            roles == 2   ? "driver"
            : roles == 1 ? "integrator"
                         : "method",
            count == 1 ? " only" : "s");
    appendf(msg, sizeof msg, "; %s accepts ", mi->name);
    if (mi->capabilities & PN_CAP_SPP) appendf(msg, sizeof msg, "--spp, ");
    if (mi->capabilities & PN_CAP_THRESHOLD) appendf(msg, sizeof msg, "--threshold, ");
    option_flags(o->integrator, msg, sizeof msg);
    appendf(msg, sizeof msg, "; the %s driver accepts ", md->name);
    option_flags(o->driver, msg, sizeof msg);
    return usage_error("render", "%s", msg);
}

static uint64_t option_methods(int option) {
    uint64_t mask = 0;
    for (int m = 0; m < pn_method_count(); m++)
        if (pn_option_applies(option, m)) mask |= 1ull << m;
    return mask;
}

static uint64_t cap_methods(uint32_t cap) {
    uint64_t mask = 0;
    for (int m = 0; m < pn_method_count(); m++)
        if (pn_method_get(m)->role == PN_METHOD_INTEGRATOR && (pn_method_get(m)->capabilities & cap)) mask |= 1ull << m;
    return mask;
}

/* The value of --integrator / --driver given anywhere in argv (for `--help` before them). */
static int scan_method(int argc, char **argv, const char *flag, pn_method_role role) {
    size_t n = strlen(flag);
    for (int i = 1; i < argc; i++) {
        const char *value = NULL;
        if (strcmp(argv[i], flag) == 0 && i + 1 < argc)
            value = argv[i + 1];
        else if (strncmp(argv[i], flag, n) == 0 && argv[i][n] == '=')
            value = argv[i] + n + 1;
        if (value) return pn_method_find(role, value);
    }
    return -1;
}

int parse_render_args(int argc, char **argv, render_options *o) {
    const char *cmd = "render";
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    const char *positional = NULL, *value;
    int kind;
    o->integrator = pn_method_find_kind(PN_METHOD_INTEGRATOR, PN_INTEGRATOR_DEFAULT);
    o->driver = pn_method_find_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT);
    o->settings.options = o->options;
    pn_context ctx = pn_context_new(); /* for the messages of pn_options_set only */
    if (!ctx) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    int code = -1;
#define FAIL(expr)                                                                                                     \
    do {                                                                                                               \
        code = (expr);                                                                                                 \
        goto done;                                                                                                     \
    } while (0)
#define NEED_VALUE()                                                                                                   \
    do {                                                                                                               \
        if ((value = scanner_value(&s)) == NULL) FAIL(EXIT_USAGE);                                                     \
    } while (0)
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (o->scene_path) FAIL(usage_error(cmd, "unexpected argument '%s'", positional));
            o->scene_path = positional;
            continue;
        }
        const char *name = s.name;
        if (strcmp(name, "-h") == 0 || strcmp(name, "--help") == 0) {
            print_render_help(stdout, scan_method(argc, argv, "--integrator", PN_METHOD_INTEGRATOR),
                              scan_method(argc, argv, "--driver", PN_METHOD_DRIVER));
            FAIL(EXIT_OK);
        } else if (strcmp(name, "--max-image-pixels") == 0) {
            NEED_VALUE();
            if (!parse_pixel_limit(cmd, name, value, &o->max_image_pixels)) FAIL(EXIT_USAGE);
        } else if (strcmp(name, "--quiet") == 0 || strcmp(name, "-q") == 0) {
            if (!scanner_no_value(&s)) FAIL(EXIT_USAGE);
            o->quiet = 1;
        } else if (strcmp(name, "-o") == 0 || strcmp(name, "--output") == 0) {
            NEED_VALUE();
            if (!is_writable_image_name(value))
                FAIL(bad_value(cmd, name, value, "a file name ending in .exr, .pfm or .png"));
            o->output_path = value;
        } else if (strcmp(name, "--aov-png") == 0) {
            if (!scanner_no_value(&s)) FAIL(EXIT_USAGE);
            o->aov_png = 1;
        } else if (strcmp(name, "--png") == 0) {
            NEED_VALUE();
            if (!ends_with(value, ".png")) FAIL(bad_value(cmd, name, value, "a file name ending in .png"));
            o->png_path = value;
        } else if (strcmp(name, "--stats") == 0) {
            NEED_VALUE();
            if (value[0] == '\0') FAIL(bad_value(cmd, name, value, "a file name"));
            o->stats_path = value;
        } else if (strcmp(name, "--exposure") == 0) {
            NEED_VALUE();
            if (!parse_double(value, &o->exposure) || o->exposure > 64.0 || o->exposure < -64.0)
                FAIL(bad_value(cmd, name, value, "a number of stops between -64 and 64"));
        } else if (strcmp(name, "--integrator") == 0 || strcmp(name, "--driver") == 0) {
            pn_method_role role = name[2] == 'i' ? PN_METHOD_INTEGRATOR : PN_METHOD_DRIVER;
            NEED_VALUE();
            int m = pn_method_find(role, value);
            if (m < 0) {
                char names[512];
                method_names(role, names, sizeof names);
                FAIL(bad_value(cmd, name, value, names));
            }
            if (role == PN_METHOD_INTEGRATOR)
                o->integrator = m;
            else
                o->driver = m;
        } else if (strcmp(name, "--spp") == 0) {
            long n;
            NEED_VALUE();
            if (!parse_long(value, 1, UINT32_MAX, &n)) FAIL(bad_value(cmd, name, value, "an integer >= 1"));
            o->settings.spp = (uint32_t)n;
            o->has_spp = 1;
        } else if (strcmp(name, "--threshold") == 0) {
            NEED_VALUE();
            if (!parse_double(value, &o->settings.threshold) || !(o->settings.threshold > 0.0))
                FAIL(bad_value(cmd, name, value, "a finite number > 0"));
            o->has_threshold = 1;
        } else if (strcmp(name, "--resolution") == 0) {
            NEED_VALUE();
            if (!parse_resolution(value, &o->settings.width, &o->settings.height))
                FAIL(bad_value(cmd, name, value, "WxH with each side from 1 to 65536"));
        } else if (strcmp(name, "--crop") == 0) {
            NEED_VALUE();
            if (!parse_crop(value, o->settings.crop))
                FAIL(bad_value(cmd, name, value, "x0,x1,y0,y1 with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1"));
            o->settings.has_crop = 1;
        } else if (strcmp(name, "--threads") == 0) {
            long n;
            NEED_VALUE();
            if (!parse_long(value, 0, PN_MAX_THREADS, &n)) {
                char expected[64];
                snprintf(expected, sizeof expected, "an integer from 0 to %d (0 = all cores)", PN_MAX_THREADS);
                FAIL(bad_value(cmd, name, value, expected));
            }
            o->settings.threads = (int)n;
        } else if (strcmp(name, "--seed") == 0) {
            NEED_VALUE();
            if (!parse_u64(value, &o->settings.seed)) FAIL(bad_value(cmd, name, value, "an unsigned 64-bit integer"));
        } else if (strcmp(name, "--aov") == 0 || strcmp(name, "--aovs") == 0) {
            char bad[64], names[512];
            NEED_VALUE();
            if (!parse_aovs(value, &o->settings.aovs, bad, sizeof bad)) {
                format_aov_names(all_aovs(), names, sizeof names);
                FAIL(usage_error(cmd, "unknown AOV '%s' in %s: expected %s or all", bad, name, names));
            }
        } else if (name[0] == '-' && name[1] == '-' && pn_option_find(name + 2) >= 0) {
            /* A method option of the table: --NAME is option NAME. */
            int index = pn_option_find(name + 2);
            const pn_option_info *info = pn_option_get(index);
            if (info->type == PN_OPTION_FLAG) {
                if (!scanner_no_value(&s)) FAIL(EXIT_USAGE);
                value = "1";
            } else {
                NEED_VALUE();
            }
            if (pn_options_set(ctx, o->options, info->name, value) != PN_OK) {
                char expected[512];
                pn_option_describe(index, expected, sizeof expected);
                FAIL(bad_value(cmd, name, value, expected));
            }
        } else {
            FAIL(usage_error(cmd, "unknown option '%s'", s.argv[s.index]));
        }
    }
    const pn_method_info *mi = pn_method_get(o->integrator), *md = pn_method_get(o->driver);
    o->settings.integrator = (pn_integrator_kind)mi->kind;
    o->settings.driver = (pn_driver_kind)md->kind;
    { /* AOVs: drivers with their own AOVs write only those */
        const uint32_t own = driver_own_aovs();
        char names[512];
        int own_only = (md->capabilities & PN_CAP_OWN_AOVS) != 0;
        if (o->settings.aovs == all_aovs()) {
            o->settings.aovs = own_only ? md->aovs : all_aovs() & ~own;
            /* "all" holds melanopic_edi only where it can be computed: in spectral mode, by an
             * integrator that declares it (asked for by name elsewhere, it is refused). */
            double spectral = 0.0;
            int si = pn_option_find("spectral");
            if (si >= 0 && pn_options_is_set(o->options, si)) pn_options_get(o->options, si, &spectral, NULL, 0);
            if (!(spectral != 0.0 && (mi->aovs & PN_AOV_MELANOPIC_EDI)))
                o->settings.aovs &= ~(uint32_t)PN_AOV_MELANOPIC_EDI;
        }
        if (own_only && (o->settings.aovs & ~md->aovs)) {
            format_aov_names(md->aovs, names, sizeof names);
            FAIL(usage_error(cmd, "with --driver %s only the AOVs %s exist", md->name, names));
        }
        if (!own_only && (o->settings.aovs & own)) {
            format_aov_names(own, names, sizeof names);
            FAIL(usage_error(cmd, "the AOVs %s need --driver", names));
        }
    }
    if (o->scene_path == NULL) FAIL(usage_error(cmd, "missing the scene file"));
    if (o->has_spp && o->has_threshold) FAIL(usage_error(cmd, "--spp and --threshold exclude each other"));
    /* Everything given must apply to the chosen methods (the table says which). */
    for (int i = 0; i < pn_option_count(); i++) {
        if (!pn_options_is_set(o->options, i) || pn_option_applies(i, o->integrator) || pn_option_applies(i, o->driver))
            continue;
        char flag[96];
        snprintf(flag, sizeof flag, "--%s", pn_option_get(i)->name);
        FAIL(not_applicable(o, flag, option_methods(i)));
    }
    if (o->has_spp && !(mi->capabilities & PN_CAP_SPP)) FAIL(not_applicable(o, "--spp", cap_methods(PN_CAP_SPP)));
    if (o->has_threshold && !(mi->capabilities & PN_CAP_THRESHOLD))
        FAIL(not_applicable(o, "--threshold", cap_methods(PN_CAP_THRESHOLD)));
    if (o->settings.aovs && o->output_path && !ends_with(o->output_path, ".exr"))
        FAIL(usage_error(cmd, "--aov needs an .exr output (got '%s')", o->output_path));
done:
    pn_context_free(ctx);
    return code;
#undef FAIL
#undef NEED_VALUE
}

/* ---------------------------------------------------------------------------------------- */
/* Help, from the table */

static const char render_help_head[] =
    "usage: penumbra render SCENE.pbrt [options]\n"
    "\n"
    "Renders SCENE.pbrt with one integrator (how the light at a pixel is estimated) and one driver\n"
    "(which pixels are evaluated). 'penumbra methods' lists them; 'penumbra render --integrator X\n"
    "--help' shows the options of X only.\n"
    "\n"
    "output:\n"
    "  -o, --output FILE      image to write: .exr (beauty + AOV layers), .pfm or .png\n"
    "                         (default: SCENE name with .exr, in the current directory)\n"
    "  --png FILE             also write an sRGB PNG preview\n"
    "  --exposure E           exposure of the PNG preview in stops (default 0)\n"
    "  --aov NAMES            extra EXR layers, comma-separated, or 'all' (see below)\n"
    "  --aov-png              also write each single-channel AOV as a false-colour PNG with a\n"
    "                         colour bar: OUT.passes.png, OUT.shadow_rays.png, ...\n"
    "  --stats FILE           write render statistics as JSON (docs/stats-json.md)\n"
    "  --quiet                no progress bar and no summary (warnings are still shown)\n"
    "\n"
    "methods and sampling:\n"
    "  --integrator NAME      %s (default reference)\n"
    "  --driver NAME          %s (default tiles)\n"
    "  --spp N                fixed number of eye rays per pixel (N >= 1), where the integrator\n"
    "                         takes one\n"
    "  --threshold T          adaptive: add eye rays until the relative variance s^2/L^2 of the\n"
    "                         pixel is below T (T > 0; default 0.01); excludes --spp\n"
    "  --seed S               seed of the random sequences (unsigned 64-bit, default 0)\n"
    "\n"
    "image and machine:\n"
    "  --resolution WxH       override the film resolution (each 1..65536)\n"
    "  --crop x0,x1,y0,y1     render only this window, in fractions of the image as pbrt's\n"
    "                         cropwindow: 0 <= x0 < x1 <= 1, 0 <= y0 < y1 <= 1\n"
    "  --threads N            worker threads (default 0 = all cores, at most 1024)\n" MAX_IMAGE_PIXELS_HELP;

static const char render_help_tail[] =
    "\n"
    "Options taking a value accept '--option VALUE' and '--option=VALUE'. An option that does not\n"
    "apply to the chosen integrator or driver is an error (exit 2).\n"
    "On Ctrl-C the render stops after the current tiles; the partial image is not written to\n"
    "the output path but to NAME.partial.EXT beside it, and the exit status is 130.\n";

/* Prints `text` wrapped at 96 columns, every line indented by `indent`, the first after `lead`. */
static void print_wrapped(FILE *out, const char *lead, int indent, const char *text) {
    int col = fprintf(out, "%s", lead);
    if (col > indent) {
        fputc('\n', out);
        col = 0;
    }
    for (; col < indent; col++) fputc(' ', out);
    const char *p = text;
    int first = 1;
    while (*p) {
        while (*p == ' ') p++;
        size_t word = strcspn(p, " ");
        if (word == 0) break;
        if (!first && col + 1 + (int)word > 96) {
            fputc('\n', out);
            for (col = 0; col < indent; col++) fputc(' ', out);
        } else if (!first) {
            fputc(' ', out);
            col++;
        }
        col += fprintf(out, "%.*s", (int)word, p);
        p += word;
        first = 0;
    }
    fputc('\n', out);
}

/* One option: "  --name VALUE   help (unit; default D; VALUE: what it must be)". */
static void print_option(FILE *out, int index) {
    const pn_option_info *info = pn_option_get(index);
    char lead[96], text[1536], expected[512], def[256] = "";
    snprintf(lead, sizeof lead, "  --%s%s", info->name, info->type == PN_OPTION_FLAG ? "" : " VALUE");
    pn_option_describe(index, expected, sizeof expected);
    pn_options_get(NULL, index, NULL, def, sizeof def);
    snprintf(text, sizeof text, "%s.%s%s%s %s%s%s", info->help, info->unit[0] ? " Unit: " : "", info->unit,
             info->unit[0] ? "." : "", info->type == PN_OPTION_FLAG ? "" : "Default ",
             info->type == PN_OPTION_FLAG ? "" : (def[0] ? def : "none"), info->type == PN_OPTION_FLAG ? "" : ";");
    if (info->type != PN_OPTION_FLAG) appendf(text, sizeof text, " %s.", expected);
    print_wrapped(out, lead, 26, text);
}

static void print_method_options(FILE *out, int m) {
    const pn_method_info *mi = pn_method_get(m);
    char head[512], aovs[512];
    snprintf(head, sizeof head, "%s %s: %s", mi->name, mi->role == PN_METHOD_DRIVER ? "(driver)" : "(integrator)",
             mi->description);
    fputc('\n', out);
    print_wrapped(out, "", 0, head);
    if (mi->paper[0]) print_wrapped(out, "  paper: ", 14, mi->paper);
    print_wrapped(out, "  computes: ", 14, mi->computes);
    if (mi->role == PN_METHOD_INTEGRATOR) {
        char sampling[128];
        if (mi->capabilities & PN_CAP_SPP)
            snprintf(sampling, sizeof sampling, "--spp (default %u%s)%s", mi->default_spp,
                     mi->default_spp ? "" : ": adaptive", mi->capabilities & PN_CAP_THRESHOLD ? " or --threshold" : "");
        else
            snprintf(sampling, sizeof sampling, "%s", mi->capabilities & PN_CAP_THRESHOLD ? "--threshold" : "none");
        print_wrapped(out, "  sampling: ", 14, sampling);
    }
    if (mi->aovs) {
        format_aov_names(mi->aovs, aovs, sizeof aovs);
        print_wrapped(out, "  AOVs: ", 14, aovs);
    }
    int any = 0;
    for (int i = 0; i < pn_option_count(); i++)
        if (pn_option_applies(i, m)) {
            print_option(out, i);
            any = 1;
        }
    if (!any) fprintf(out, "  (no options of its own)\n");
}

void print_render_help(FILE *out, int integrator, int driver) {
    char integrators[512], drivers[512], aovs[512];
    method_names(PN_METHOD_INTEGRATOR, integrators, sizeof integrators);
    method_names(PN_METHOD_DRIVER, drivers, sizeof drivers);
    fprintf(out, render_help_head, integrators, drivers);
    format_aov_names(PN_AOV_COMMON, aovs, sizeof aovs);
    fprintf(out, "\nAOVs of every integrator under the tiles driver: %s; each method lists its own.\n", aovs);
    if (integrator >= 0 || driver >= 0) {
        if (integrator >= 0) print_method_options(out, integrator);
        print_method_options(out, driver >= 0 ? driver : pn_method_find_kind(PN_METHOD_DRIVER, PN_DRIVER_DEFAULT));
    } else {
        for (int m = 0; m < pn_method_count(); m++) print_method_options(out, m);
    }
    fputs(render_help_tail, out);
}

/* `penumbra methods --markdown`: the table as the Markdown of docs/options.md. */
static void print_markdown(void) {
    printf("# Methods and their options\n\n"
           "Generated by `penumbra methods --markdown` from the method table (src/integrators/registry.c);\n"
           "a test checks that this page matches it. Every option is a flag of `penumbra render`\n"
           "(`--NAME VALUE`) and a name for `pn_options_set()`. An option that does not apply to the chosen\n"
           "integrator or driver is refused (exit 2).\n\n"
           "| method | kind | computes | paper | sampling | options |\n|---|---|---|---|---|---|\n");
    for (int m = 0; m < pn_method_count(); m++) {
        const pn_method_info *mi = pn_method_get(m);
        char opts[1024] = "", sampling[64] = "";
        int n = 0;
        for (int i = 0; i < pn_option_count(); i++)
            if (pn_option_applies(i, m)) appendf(opts, sizeof opts, "%s`%s`", n++ ? ", " : "", pn_option_get(i)->name);
        if (mi->role == PN_METHOD_INTEGRATOR) {
            if (mi->capabilities & PN_CAP_SPP)
                appendf(sampling, sizeof sampling, "spp (default %u%s)", mi->default_spp,
                        mi->default_spp ? "" : ": adaptive");
            if (mi->capabilities & PN_CAP_THRESHOLD)
                appendf(sampling, sizeof sampling, "%sthreshold", sampling[0] ? ", " : "");
        }
        printf("| `%s` | %s | %s | %s | %s | %s |\n", mi->name, mi->role == PN_METHOD_DRIVER ? "driver" : "integrator",
               mi->computes, mi->paper[0] ? mi->paper : "-", sampling[0] ? sampling : "-", n ? opts : "-");
    }
    printf("\n## Options\n\n| option | type | default | accepts | unit | applies to | meaning |\n"
           "|---|---|---|---|---|---|---|\n");
    static const char *const types[] = {"integer", "number", "flag", "choice", "set", "list", "text"};
    for (int i = 0; i < pn_option_count(); i++) {
        const pn_option_info *info = pn_option_get(i);
        char expected[512], def[256] = "", where[512] = "";
        pn_option_describe(i, expected, sizeof expected);
        pn_options_get(NULL, i, NULL, def, sizeof def);
        int n = 0;
        for (int m = 0; m < pn_method_count(); m++)
            if (pn_option_applies(i, m))
                appendf(where, sizeof where, "%s`%s`", n++ ? ", " : "", pn_method_get(m)->name);
        printf("| `--%s` | %s | %s | %s | %s | %s | %s |\n", info->name, types[info->type], def[0] ? def : "none",
               expected, info->unit[0] ? info->unit : "-", where, info->help);
    }
    printf("\n## Statistics\n\nWhat a render measures, from the statistics table (src/render/stats.c): the `stats` "
           "of the\nstatistics JSON ([stats-json.md](stats-json.md)) and the names for `pn_stats_get()`. `merge` "
           "says how\n`penumbra merge` combines the parts of one image.\n\n"
           "| statistic | type | unit | produced by | merge | meaning |\n|---|---|---|---|---|---|\n");
    static const char *const stat_types[] = {"count", "seconds", "mean", "max", "integer", "flag"};
    static const char *const merges[] = {"sum",         "max",          "pixel-weighted mean", "any",
                                         "whole width", "whole height", "first part's"};
    for (int i = 0; i < pn_stat_count(); i++) {
        const pn_stat_info *si = pn_stat_get(i);
        char where[512] = "";
        int n = 0;
        for (int m = 0; si->group[0] && m < pn_method_count(); m++)
            if (pn_stat_applies(i, m)) appendf(where, sizeof where, "%s`%s`", n++ ? ", " : "", pn_method_get(m)->name);
        printf("| `%s`%s | %s | %s | %s | %s | %s |\n", si->name, si->per_rank ? " (per rank)" : "",
               stat_types[si->type], si->unit[0] ? si->unit : "-", si->group[0] ? where : "every render",
               merges[si->merge], si->help);
    }
}

/* `penumbra methods [NAME]`: every method (or one) with what it computes and its options. */
int command_methods(int argc, char **argv) {
    const char *cmd = "methods";
    const char *positional = NULL;
    const char *only = NULL;
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    int kind;
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (only) return usage_error(cmd, "unexpected argument '%s'", positional);
            only = positional;
        } else if (strcmp(s.name, "--markdown") == 0) {
            if (!scanner_no_value(&s)) return EXIT_USAGE;
            print_markdown();
            return EXIT_OK;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs("usage: penumbra methods [NAME] [--markdown]\n\nLists every integrator and driver of penumbra: what "
                  "it computes, "
                  "its paper,\nits capabilities, AOVs and options (or only the method NAME); --markdown prints "
                  "the\ntables of docs/options.md.\n",
                  stdout);
            return EXIT_OK;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    int shown = 0;
    for (int m = 0; m < pn_method_count(); m++) {
        if (only && strcmp(pn_method_get(m)->name, only) != 0) continue;
        if (!shown && !only)
            printf("penumbra's methods: integrators estimate the light at pixels, drivers choose "
                   "the pixels.\n");
        print_method_options(stdout, m);
        const pn_method_info *mi = pn_method_get(m);
        char caps[256] = "";
        static const struct {
            uint32_t bit;
            const char *name;
        } cap_names[] = {{PN_CAP_PER_PIXEL, "per pixel"},
                         {PN_CAP_PER_BLOCK, "per block"},
                         {PN_CAP_WHOLE_IMAGE, "whole image"},
                         {PN_CAP_PROGRESSIVE, "progressive drivers"},
                         {PN_CAP_CROP, "crops"},
                         {PN_CAP_DISTRIBUTED, "distributed"},
                         {PN_CAP_OWN_AOVS, "own AOVs only"}};
        for (size_t i = 0; i < sizeof cap_names / sizeof cap_names[0]; i++)
            if (mi->capabilities & cap_names[i].bit)
                appendf(caps, sizeof caps, "%s%s", caps[0] ? ", " : "", cap_names[i].name);
        if (caps[0]) print_wrapped(stdout, "  works: ", 14, caps);
        char names[2048] = "";
        for (int i = 0; i < pn_stat_count(); i++)
            if (pn_stat_get(i)->group[0] && pn_stat_applies(i, m))
                appendf(names, sizeof names, "%s%s", names[0] ? ", " : "", pn_stat_get(i)->name);
        if (names[0]) print_wrapped(stdout, "  statistics: ", 14, names);
        shown++;
    }
    if (!shown) return usage_error(cmd, "unknown method '%s'", only);
    return EXIT_OK;
}
