/* main.c — the `penumbra` command-line program: `render`, `diff` and `info`, built on the public
 * header only.
 *
 * Everything here is argument parsing and reporting. Numbers are parsed strictly (the whole
 * string must be a number in range), problems with the command line exit with status 2 and a
 * one-line message that names the option, and library errors are mapped onto the exit codes
 * documented in README.md:
 *
 *   0 success, 2 usage, 3 bad input, 4 system error, 70 internal error, 130 interrupted.
 *
 * No file is ever left half-written: the library writes images to a temporary name and renames
 * them, and the statistics JSON written here does the same.
 */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L /* sigaction, clock_gettime, isatty */
#endif

#include <penumbra/penumbra.h>

#include <errno.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

enum {
    EXIT_OK = 0,
    EXIT_USAGE = 2,
    EXIT_BAD_INPUT = 3,
    EXIT_SYSTEM = 4,
    EXIT_INTERNAL = 70,
    EXIT_INTERRUPTED = 130
};

/* Defaults documented in penumbra.h; the CLI passes them explicitly so that --help and the
 * statistics JSON state exactly what was asked for. */
#define CLI_DEFAULT_THRESHOLD 0.01
#define CLI_DEFAULT_SHADOW_RAYS 4u
#define CLI_DEFAULT_MAX_SHADOW_RAYS 20000u

/* ---------------------------------------------------------------------------------------- */
/* Help texts */

static const char main_help[] =
    "penumbra - many-light renderer for pbrt-v4 scenes\n"
    "\n"
    "usage:\n"
    "  penumbra render SCENE.pbrt [options]   render a scene to EXR (and PNG)\n"
    "  penumbra diff REFERENCE IMAGE [options] compare two images (RMSE, relMSE, ...)\n"
    "  penumbra info SCENE.pbrt               describe a scene: geometry, lights, materials\n"
    "  penumbra --help | --version\n"
    "\n"
    "Run 'penumbra COMMAND --help' for the options of a command.\n"
    "\n"
    "exit status: 0 success, 2 usage error, 3 bad input (scene or image file), 4 system error\n"
    "(I/O, memory), 70 internal error, 130 interrupted.\n";

static const char render_help[] =
    "usage: penumbra render SCENE.pbrt [options]\n"
    "\n"
    "Renders SCENE.pbrt: direct lighting through specular chains, with the reference integrator\n"
    "or Iterative Adaptive Sampling (ias).\n"
    "\n"
    "output:\n"
    "  -o, --output FILE      image to write: .exr (beauty + AOV layers), .pfm or .png\n"
    "                         (default: SCENE name with .exr, in the current directory)\n"
    "  --png FILE             also write an sRGB PNG preview\n"
    "  --exposure E           exposure of the PNG preview in stops (default 0)\n"
    "  --aov NAMES            extra EXR layers, comma-separated: shadow_rays, eye_rays,\n"
    "                         relative_variance, depth, normal, albedo; for ias also passes,\n"
    "                         aa_regions, clusters, visible_fraction; or 'all'\n"
    "  --aov-png              also write each single-channel AOV as a false-colour PNG with a\n"
    "                         colour bar: OUT.passes.png, OUT.shadow_rays.png, ...\n"
    "  --stats FILE           write render statistics as JSON\n"
    "  --quiet                no progress bar and no summary (warnings are still shown)\n"
    "\n"
    "sampling:\n"
    "  --integrator NAME      'reference' (the default: Donikian et al. 2006, section 5.1) or\n"
    "                         'ias' (Iterative Adaptive Sampling, the same paper)\n"
    "  --spp N                fixed number of eye rays per pixel (N >= 1)\n"
    "  --threshold T          adaptive: add eye rays until the relative variance s^2/L^2 of the\n"
    "                         pixel is below T (T > 0; default 0.01); excludes --spp\n"
    "  --shadow-rays N        shadow rays per eye ray, 1..65536 (default 4)\n"
    "  --max-samples N        at most N shadow rays per pixel (default 20000)\n"
    "  --seed S               seed of the random sequences (unsigned 64-bit, default 0)\n"
    "  --light-sampler NAME   reference only: 'irradiance' (the default: a PDF over all lights by\n"
    "                         unoccluded irradiance, section 5.1) or 'bvh' (pbrt-v4's light BVH)\n"
    "\n"
    "ias only (the paper's values by default):\n"
    "  --cluster-solid-angle A  largest solid angle of a light cluster seen from a point\n"
    "                         (steradians, default 0.02)\n"
    "  --aa-rays N            eye rays per pixel grouped into antialiasing regions (default 32)\n"
    "  --env-regions N        regions of an environment map (default 300)\n"
    "  --max-passes N         passes per block (default 15)\n"
    "  --block-size N         pixels per side of a block, 8..32 (default 8: the paper's 8x8)\n"
    "\n"
    "VPL integrators: 'vpl' (every point against every VPL, the reference of IlluminationCut),\n"
    "'lightcuts' (Walter et al. 2005) and 'illumcut' (Bus et al. 2015); --spp N eye rays per\n"
    "pixel (default 1):\n"
    "  --vpls N               virtual point lights to trace (default 600000)\n"
    "  --vpl-depth N          light path bounces that leave VPLs (default 10)\n"
    "  --vpl-clamp F          minimum point-VPL distance, fraction of the scene radius (0.05)\n"
    "  --vpl-direct-only      direct light only, as reference, ias and contour compute: the lights\n"
    "                         themselves as VPLs (points sampled on area lights and environment\n"
    "                         maps), no bounces; no --vpl-depth, and no clamp unless --vpl-clamp\n"
    "  --error E              relative error bound of lightcuts and illumcut (default 0.01)\n"
    "  --max-cut N            lightcuts: at most N clusters per point (default: no limit)\n"
    "  --visibility MODE      illumcut: 'exact' (a shadow ray per point and pair, the default)\n"
    "                         or 'sampling' (adaptive visibility sampling, Algorithm 2)\n"
    "  AOVs: bound_evaluations, cut_size, phase1 (illumcut's approximate image)\n"
    "contour (Vedel 1993, Approximate Contour Integration; --integrator contour) and contour-mc\n"
    "(its comparison, adaptive Monte Carlo sampling of the source after Kok & Jansen 1992):\n"
    "rectangles and triangles of emitting meshes on diffuse receivers; every other light (and\n"
    "glossy receivers) as by 'reference' with --shadow-rays. Fixed --spp (default 1).\n"
    "  --contour-grid N       first-level samples per side of a source, 2..65 (default 3: 9)\n"
    "  --contour-steps N      dichotomy steps, 1..12 (default 5)\n"
    "  --contour-span N       longest span of pixels sharing first-level rays, 1..64 (default 8)\n"
    "  --contour-off LIST     switch parts off for comparisons, comma-separated: shaft (shaft\n"
    "                         culling), spans (integrate every pixel), validity (the corner\n"
    "                         test, Fig. 6's failure), adaptive (fixed first-level density),\n"
    "                         restarts (accept inconsistencies instead of restarting finer);\n"
    "                         our departures: islands (probes of a nearby pixel's islands),\n"
    "                         half (partial pattern checks in uniform runs), scouts (probes in\n"
    "                         agreeing squares), linear (linear runs without a middle integration)\n"
    "  --mc-threshold T       contour-mc: refine a cell while its standard error exceeds T times\n"
    "                         the source's unoccluded form factor (default 0.002)\n"
    "  --mc-max-rays N        contour-mc: shadow rays per source and point, at most (default 256)\n"
    "  --aov gradient         contour: gradient of the irradiance luminance (eq. 5, 8-10)\n"
    "\n"
    "image and machine:\n"
    "  --resolution WxH       override the film resolution (each 1..65536)\n"
    "  --crop x0,x1,y0,y1     render only this window, in fractions of the image as pbrt's\n"
    "                         cropwindow: 0 <= x0 < x1 <= 1, 0 <= y0 < y1 <= 1\n"
    "  --threads N            worker threads (default 0 = all cores)\n"
    "\n"
    "progressive drivers (Guo 1998, Directional Coherence Maps):\n"
    "  --driver NAME          'tiles' (the default), 'full' (every pixel of the work image, then\n"
    "                         the Gaussian filter: the baseline), 'dcm', 'painter' (Painter &\n"
    "                         Sloan 1989) or 'uniform' (uniform subsampling, bilinear)\n"
    "  --work-scale S         the work image is S x S the output resolution (default 3)\n"
    "  --snapshots P1,P2,...  write the approximate image when P% of the work pixels are\n"
    "                         evaluated, beside the output: out.exr -> out-6pct.exr\n"
    "  --snapshot-every SEC   and every SEC seconds (out-12.5pct.exr); SIGUSR1 writes one now\n"
    "  --stop-at P            stop after P% of the work pixels and write the approximate image;\n"
    "                         with a lower --threshold: the paper's confidence relocation\n"
    "  --raw-radiance         interpolate radiance itself, not (radiance - emitted) / albedo\n"
    "  --no-light-guide       divide by the albedo only, not also by the lights' unshadowed irradiance\n"
    "  --primary-grid G       G x G primary rays per work pixel measure its albedo and the\n"
    "                         emitted radiance it sees where they change, 1..8 (default 3);\n"
    "                         along emitters, reference at a fixed --spp traces its own eye\n"
    "                         rays instead\n"
    "  AOVs of these drivers: sampling_pattern, block_map, block_direction\n"
    "\n"
    "Options taking a value accept '--option VALUE' and '--option=VALUE'.\n"
    "On Ctrl-C the render stops after the current tiles; the partial image is not written to\n"
    "the output path but to NAME.partial.EXT beside it, and the exit status is 130.\n";

static const char diff_help[] =
    "usage: penumbra diff REFERENCE IMAGE [options]\n"
    "\n"
    "Compares IMAGE against REFERENCE (EXR, PFM, HDR, PNG, TGA or JPG; both the same size) and\n"
    "prints RMSE, relMSE (mean of (a-b)^2 / (b^2 + epsilon), epsilon 0.01), the relative L1 and L2\n"
    "norms of the difference, the mean absolute error and both mean luminances.\n"
    "\n"
    "options:\n"
    "  --error-image FILE     write |IMAGE - REFERENCE| x 16 as an image (.exr, .pfm or .png)\n"
    "  --json                 print the metrics as JSON instead of text\n";

static const char info_help[] =
    "usage: penumbra info SCENE.pbrt\n"
    "\n"
    "Loads SCENE.pbrt and prints what penumbra made of it: triangles, meshes, instances, spheres,\n"
    "lights by kind, materials and how each pbrt material was mapped, textures, bounds, film\n"
    "resolution, load times and the warnings raised while loading.\n";

/* ---------------------------------------------------------------------------------------- */
/* Small helpers */

static int usage_error(const char *command, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* Prints "penumbra COMMAND: message (see penumbra COMMAND --help)" and returns EXIT_USAGE. */
static int usage_error(const char *command, const char *fmt, ...) {
    va_list args;
    fprintf(stderr, "penumbra%s%s: ", command ? " " : "", command ? command : "");
    va_start(args, fmt);
    vfprintf(stderr, fmt, args);
    va_end(args);
    if (command)
        fprintf(stderr, " (see penumbra %s --help)\n", command);
    else
        fprintf(stderr, " (see penumbra --help)\n");
    return EXIT_USAGE;
}

static int exit_code_for(pn_status status) {
    switch (status) {
    case PN_OK:
        return EXIT_OK;
    case PN_ERROR_BAD_INPUT:
    case PN_ERROR_UNSUPPORTED:
        return EXIT_BAD_INPUT;
    case PN_ERROR_IO:
    case PN_ERROR_OUT_OF_MEMORY:
        return EXIT_SYSTEM;
    case PN_ERROR_CANCELLED:
        return EXIT_INTERRUPTED;
    default:
        return EXIT_INTERNAL;
    }
}

/* Reports a failed library call and returns the matching exit code. */
static int report_failure(pn_context ctx, pn_status status) {
    const char *message = ctx ? pn_context_error_message(ctx) : "";
    if (message == NULL || message[0] == '\0')
        message = pn_status_string(status);
    fprintf(stderr, "penumbra: %s\n", message);
    return exit_code_for(status);
}

static double monotonic_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int ends_with(const char *s, const char *suffix) {
    size_t n = strlen(s), m = strlen(suffix);
    if (m > n)
        return 0;
    for (size_t i = 0; i < m; i++) {
        char a = s[n - m + i], b = suffix[i];
        if (a >= 'A' && a <= 'Z')
            a = (char)(a - 'A' + 'a');
        if (a != b)
            return 0;
    }
    return 1;
}

/* Image formats pn_image_write understands, by extension. */
static int is_writable_image_name(const char *path) {
    return ends_with(path, ".exr") || ends_with(path, ".pfm") || ends_with(path, ".png");
}

/* Fails early, before a long render, when the folder of `path` is missing or not writable. */
static int check_output_folder(const char *path) {
    const char *slash = strrchr(path, '/');
    char folder[4096];
    if (slash == NULL) {
        strcpy(folder, ".");
    } else if (slash == path) {
        strcpy(folder, "/");
    } else {
        size_t n = (size_t)(slash - path);
        if (n >= sizeof folder) {
            fprintf(stderr, "penumbra: %s: path too long\n", path);
            return EXIT_SYSTEM;
        }
        memcpy(folder, path, n);
        folder[n] = '\0';
    }
    if (access(folder, W_OK | X_OK) != 0) {
        fprintf(stderr, "penumbra: cannot write '%s': %s: %s\n", path, folder, strerror(errno));
        return EXIT_SYSTEM;
    }
    return EXIT_OK;
}

/* A missing or unreadable input file is bad input (exit 3), whatever the reader would call it. */
static int check_input_file(const char *path) {
    if (access(path, R_OK) != 0) {
        fprintf(stderr, "penumbra: %s: %s\n", path, strerror(errno));
        return EXIT_BAD_INPUT;
    }
    return EXIT_OK;
}

/* "dir/name.pbrt" -> "name.exr" (in the current folder). Caller frees. */
static char *default_output_name(const char *scene_path) {
    const char *base = strrchr(scene_path, '/');
    base = base ? base + 1 : scene_path;
    size_t n = strlen(base);
    if (ends_with(base, ".pbrt"))
        n -= 5;
    if (n == 0) {
        base = "out";
        n = 3;
    }
    char *name = malloc(n + 5);
    if (name == NULL)
        return NULL;
    memcpy(name, base, n);
    memcpy(name + n, ".exr", 5);
    return name;
}

/* "out/x.exr" -> "out/x.partial.exr". Caller frees. */
static char *partial_output_name(const char *path) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (dot == NULL || (slash && dot < slash))
        dot = path + strlen(path);
    size_t stem = (size_t)(dot - path);
    size_t total = strlen(path) + sizeof ".partial";
    char *name = malloc(total);
    if (name == NULL)
        return NULL;
    memcpy(name, path, stem);
    snprintf(name + stem, total - stem, ".partial%s", dot);
    return name;
}

/* ---------------------------------------------------------------------------------------- */
/* Strict number parsing: the whole string must be a number, no leading blanks or signs where
 * they make no sense, and the value must be in range. */

static int parse_long(const char *text, long min, long max, long *out) {
    char *end = NULL;
    if (text[0] == '\0' || text[0] == ' ' || text[0] == '\t' || text[0] == '+')
        return 0;
    errno = 0;
    long value = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < min || value > max)
        return 0;
    *out = value;
    return 1;
}

static int parse_u64(const char *text, uint64_t *out) {
    char *end = NULL;
    if (text[0] < '0' || text[0] > '9')
        return 0;
    errno = 0;
    unsigned long long value = strtoull(text, &end, 10);
    if (errno != 0 || *end != '\0')
        return 0;
    *out = (uint64_t)value;
    return 1;
}

static int parse_double(const char *text, double *out) {
    char *end = NULL;
    if (text[0] == '\0' || text[0] == ' ' || text[0] == '\t')
        return 0;
    errno = 0;
    double value = strtod(text, &end);
    if (errno != 0 || end == text || *end != '\0' || !isfinite(value))
        return 0;
    *out = value;
    return 1;
}

/* "WxH" with each side in 1..65536. */
static int parse_resolution(const char *text, int *width, int *height) {
    const char *x = strchr(text, 'x');
    char left[32];
    long w, h;
    if (x == NULL || (size_t)(x - text) >= sizeof left)
        return 0;
    memcpy(left, text, (size_t)(x - text));
    left[x - text] = '\0';
    if (!parse_long(left, 1, 65536, &w) || !parse_long(x + 1, 1, 65536, &h))
        return 0;
    *width = (int)w;
    *height = (int)h;
    return 1;
}

/* "x0,x1,y0,y1" with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1. */
static int parse_crop(const char *text, float crop[4]) {
    char buffer[256];
    double v[4];
    if (strlen(text) >= sizeof buffer)
        return 0;
    strcpy(buffer, text);
    char *cursor = buffer;
    for (int i = 0; i < 4; i++) {
        char *comma = strchr(cursor, ',');
        if ((i < 3) != (comma != NULL))
            return 0;
        if (comma)
            *comma = '\0';
        if (!parse_double(cursor, &v[i]) || v[i] < 0.0 || v[i] > 1.0)
            return 0;
        cursor = comma ? comma + 1 : cursor;
    }
    if (!(v[0] < v[1]) || !(v[2] < v[3]))
        return 0;
    for (int i = 0; i < 4; i++)
        crop[i] = (float)v[i];
    return 1;
}

static const struct {
    const char *name;
    uint32_t bit;
} aov_names[] = {
    {"shadow_rays", PN_AOV_SHADOW_RAYS}, {"eye_rays", PN_AOV_EYE_RAYS},
    {"relative_variance", PN_AOV_RELATIVE_VARIANCE}, {"depth", PN_AOV_DEPTH},
    {"normal", PN_AOV_NORMAL}, {"albedo", PN_AOV_ALBEDO},
    {"passes", PN_AOV_PASSES}, {"aa_regions", PN_AOV_AA_REGIONS},
    {"clusters", PN_AOV_CLUSTERS}, {"visible_fraction", PN_AOV_VISIBLE_FRACTION},
    /* VPL integrators (issue 5) */
    {"bound_evaluations", PN_AOV_BOUND_EVALUATIONS}, {"cut_size", PN_AOV_CUT_SIZE}, {"phase1", PN_AOV_PHASE1},
    {"gradient", PN_AOV_GRADIENT}, /* contour */
    /* progressive drivers (issue 6) */
    {"sampling_pattern", PN_AOV_SAMPLING_PATTERN}, {"block_map", PN_AOV_BLOCK_MAP},
    {"block_direction", PN_AOV_BLOCK_DIRECTION},
};
#define AOV_NAME_COUNT (sizeof aov_names / sizeof aov_names[0])

/* Comma list of AOV names or "all"; on failure *bad points at the offending name (copied). */
static int parse_aovs(const char *text, uint32_t *bits, char *bad, size_t bad_size) {
    uint32_t result = 0;
    const char *cursor = text;
    if (strcmp(text, "all") == 0) {
        for (size_t i = 0; i < AOV_NAME_COUNT; i++)
            result |= aov_names[i].bit;
        *bits = result;
        return 1;
    }
    for (;;) {
        const char *comma = strchr(cursor, ',');
        size_t n = comma ? (size_t)(comma - cursor) : strlen(cursor);
        int found = 0;
        for (size_t i = 0; i < AOV_NAME_COUNT; i++) {
            if (strlen(aov_names[i].name) == n && strncmp(aov_names[i].name, cursor, n) == 0) {
                result |= aov_names[i].bit;
                found = 1;
            }
        }
        if (!found) {
            snprintf(bad, bad_size, "%.*s", (int)n, cursor);
            return 0;
        }
        if (comma == NULL)
            break;
        cursor = comma + 1;
    }
    *bits = result;
    return 1;
}

/* ---------------------------------------------------------------------------------------- */
/* Option scanning shared by the commands. An argument "--name=value" carries its value inline;
 * otherwise the value is the next argument. */

typedef struct arg_scanner {
    const char *command;
    int argc;
    char **argv;
    int index;           /* of the current argument */
    char name[64];       /* current option name without "=value" */
    const char *inline_value;
    int options_done;    /* after "--" everything is positional */
} arg_scanner;

/* Advances to the next argument. Returns 0 at the end, 1 for an option (name filled), 2 for a
 * positional argument. */
static int scanner_next(arg_scanner *s, const char **positional) {
    s->index++;
    if (s->index >= s->argc)
        return 0;
    const char *arg = s->argv[s->index];
    s->inline_value = NULL;
    if (!s->options_done && strcmp(arg, "--") == 0) {
        s->options_done = 1;
        return scanner_next(s, positional);
    }
    if (s->options_done || arg[0] != '-' || arg[1] == '\0') {
        *positional = arg;
        return 2;
    }
    const char *equals = arg[1] == '-' ? strchr(arg, '=') : NULL;
    size_t n = equals ? (size_t)(equals - arg) : strlen(arg);
    if (n >= sizeof s->name)
        n = sizeof s->name - 1;
    memcpy(s->name, arg, n);
    s->name[n] = '\0';
    s->inline_value = equals ? equals + 1 : NULL;
    return 1;
}

/* The value of the current option, or NULL after printing a usage error. */
static const char *scanner_value(arg_scanner *s) {
    if (s->inline_value)
        return s->inline_value;
    if (s->index + 1 >= s->argc) {
        usage_error(s->command, "option '%s' needs a value", s->name);
        return NULL;
    }
    s->index++;
    return s->argv[s->index];
}

/* Rejects "--flag=value" for options that take no value. */
static int scanner_no_value(arg_scanner *s) {
    if (s->inline_value) {
        usage_error(s->command, "option '%s' takes no value", s->name);
        return 0;
    }
    return 1;
}

static int bad_value(const char *command, const char *option, const char *value,
                     const char *expected) {
    return usage_error(command, "invalid value '%s' for %s: expected %s", value, option, expected);
}

/* ---------------------------------------------------------------------------------------- */
/* A small JSON writer: pretty-printed, with string escaping, written to "<path>.tmp" and renamed
 * into place when complete. */

typedef struct json_writer {
    FILE *file;
    int depth;
    int need_comma[32]; /* per nesting level: an item was written, the next needs a comma */
    int inline_items[32]; /* per nesting level: items on one line (short arrays of numbers) */
    int after_key;
} json_writer;

static void json_indent(json_writer *w) {
    fputc('\n', w->file);
    for (int i = 0; i < w->depth; i++)
        fputs("  ", w->file);
}

/* Separator and indentation before a value or a key. */
static void json_prefix(json_writer *w) {
    if (w->after_key) {
        w->after_key = 0;
        return;
    }
    if (w->depth > 0) {
        if (w->need_comma[w->depth])
            fputs(w->inline_items[w->depth] ? ", " : ",", w->file);
        if (!w->inline_items[w->depth])
            json_indent(w);
    }
    w->need_comma[w->depth] = 1;
}

static void json_raw_string(json_writer *w, const char *s) {
    fputc('"', w->file);
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        switch (*p) {
        case '"':
            fputs("\\\"", w->file);
            break;
        case '\\':
            fputs("\\\\", w->file);
            break;
        case '\n':
            fputs("\\n", w->file);
            break;
        case '\r':
            fputs("\\r", w->file);
            break;
        case '\t':
            fputs("\\t", w->file);
            break;
        case '\b':
            fputs("\\b", w->file);
            break;
        case '\f':
            fputs("\\f", w->file);
            break;
        default:
            if (*p < 0x20)
                fprintf(w->file, "\\u%04x", *p);
            else
                fputc(*p, w->file);
        }
    }
    fputc('"', w->file);
}

static void json_open(json_writer *w, char bracket, int inline_items) {
    json_prefix(w);
    fputc(bracket, w->file);
    if (w->depth < 31)
        w->depth++;
    w->need_comma[w->depth] = 0;
    w->inline_items[w->depth] = inline_items;
}

static void json_close(json_writer *w, char bracket) {
    int had_items = w->need_comma[w->depth];
    int was_inline = w->inline_items[w->depth];
    if (w->depth > 0)
        w->depth--;
    if (had_items && !was_inline)
        json_indent(w);
    fputc(bracket, w->file);
}

static void json_key(json_writer *w, const char *key) {
    json_prefix(w);
    json_raw_string(w, key);
    fputs(": ", w->file);
    w->after_key = 1;
}

static void json_string(json_writer *w, const char *key, const char *value) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    if (value)
        json_raw_string(w, value);
    else
        fputs("null", w->file);
}

static void json_double(json_writer *w, const char *key, double value) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    if (isfinite(value))
        fprintf(w->file, "%.10g", value);
    else
        fputs("null", w->file);
}

static void json_u64(json_writer *w, const char *key, uint64_t value) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    fprintf(w->file, "%llu", (unsigned long long)value);
}

static void json_int(json_writer *w, const char *key, long long value) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    fprintf(w->file, "%lld", value);
}

static void json_bool(json_writer *w, const char *key, int value) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    fputs(value ? "true" : "false", w->file);
}

static void json_null(json_writer *w, const char *key) {
    if (key)
        json_key(w, key);
    json_prefix(w);
    fputs("null", w->file);
}

static void json_begin_object(json_writer *w, const char *key) {
    if (key)
        json_key(w, key);
    json_open(w, '{', 0);
}

static void json_begin_array(json_writer *w, const char *key) {
    if (key)
        json_key(w, key);
    json_open(w, '[', 0);
}

/* An array whose items are written on one line: for short lists of numbers or names. */
static void json_begin_inline_array(json_writer *w, const char *key) {
    if (key)
        json_key(w, key);
    json_open(w, '[', 1);
}

static void json_end_object(json_writer *w) { json_close(w, '}'); }
static void json_end_array(json_writer *w) { json_close(w, ']'); }

/* Opens "<path>.tmp" for writing. Returns NULL with errno set on failure; *tmp_path is set and
 * must be freed by the caller. */
static FILE *atomic_open(const char *path, char **tmp_path) {
    size_t n = strlen(path) + 5;
    *tmp_path = malloc(n);
    if (*tmp_path == NULL)
        return NULL;
    snprintf(*tmp_path, n, "%s.tmp", path);
    return fopen(*tmp_path, "w");
}

/* Flushes and closes the temporary file and renames it to `path`; removes it on any failure.
 * Returns 0 or an errno value. */
static int atomic_commit(FILE *file, const char *tmp_path, const char *path) {
    int failed = ferror(file);
    if (fflush(file) != 0)
        failed = 1;
    int error = failed ? (errno ? errno : EIO) : 0;
    if (fclose(file) != 0 && !error)
        error = errno ? errno : EIO;
    if (!error && rename(tmp_path, path) != 0)
        error = errno;
    if (error)
        remove(tmp_path);
    return error;
}

/* ---------------------------------------------------------------------------------------- */
/* Progress bar */

typedef struct progress_state {
    double start;
    double last_draw;
    int drawn;
} progress_state;

static void format_duration(double seconds, char *out, size_t size) {
    if (!(seconds >= 0.0) || seconds > 360000.0) {
        snprintf(out, size, "--:--");
        return;
    }
    long s = (long)(seconds + 0.5);
    if (s >= 3600)
        snprintf(out, size, "%ld:%02ld:%02ld", s / 3600, (s / 60) % 60, s % 60);
    else
        snprintf(out, size, "%ld:%02ld", s / 60, s % 60);
}

static void draw_progress(progress_state *state, double fraction, double now) {
    enum { BAR_WIDTH = 30 };
    char bar[BAR_WIDTH + 1], elapsed_text[32], eta_text[32];
    if (fraction < 0.0)
        fraction = 0.0;
    if (fraction > 1.0)
        fraction = 1.0;
    int filled = (int)(fraction * BAR_WIDTH);
    for (int i = 0; i < BAR_WIDTH; i++)
        bar[i] = i < filled ? '#' : '.';
    bar[BAR_WIDTH] = '\0';
    double elapsed = now - state->start;
    format_duration(elapsed, elapsed_text, sizeof elapsed_text);
    if (fraction > 0.0)
        format_duration(elapsed * (1.0 - fraction) / fraction, eta_text, sizeof eta_text);
    else
        snprintf(eta_text, sizeof eta_text, "--:--");
    fprintf(stderr, "\r[%s] %5.1f%%  elapsed %s  ETA %s ", bar, 100.0 * fraction, elapsed_text,
            eta_text);
    fflush(stderr);
    state->drawn = 1;
    state->last_draw = now;
}

/* Called by the library from worker threads, serialised by its lock. */
static void on_progress(void *user, double fraction) {
    progress_state *state = user;
    double now = monotonic_seconds();
    if (state->drawn && now - state->last_draw < 0.1 && fraction < 1.0)
        return;
    draw_progress(state, fraction, now);
}

static void finish_progress(progress_state *state, int complete) {
    if (!state->drawn)
        return;
    if (complete)
        draw_progress(state, 1.0, monotonic_seconds());
    fputc('\n', stderr);
}

/* ---------------------------------------------------------------------------------------- */
/* Logging and Ctrl-C */

typedef struct log_options {
    int quiet;
    int show_warnings;
} log_options;

/* Warnings go to stderr; errors are reported once, by the caller, from the context message. */
static void on_log(void *user, pn_log_level level, const char *message) {
    const log_options *options = user;
    if (level == PN_LOG_ERROR)
        return;
    if (level == PN_LOG_WARNING) {
        if (options->show_warnings)
            fprintf(stderr, "penumbra: warning: %s\n", message);
        return;
    }
    if (!options->quiet)
        fprintf(stderr, "penumbra: %s\n", message);
}

static pn_context volatile interrupt_context;
static volatile sig_atomic_t interrupted;

static void on_sigint(int signo) {
    static const char note[] = "\npenumbra: interrupted; finishing the current tiles "
                               "(press Ctrl-C again to quit at once)\n";
    (void)signo;
    interrupted = 1;
    if (interrupt_context)
        pn_render_cancel(interrupt_context);
    ssize_t ignored = write(STDERR_FILENO, note, sizeof note - 1);
    (void)ignored;
}

/* ---------------------------------------------------------------------------------------- */
/* render */

typedef struct render_options {
    const char *scene_path;
    const char *output_path;
    const char *png_path;
    const char *stats_path;
    int aov_png; /* --aov-png: false-colour PNGs of the single-channel AOV layers */
    double exposure;
    int quiet;
    int has_spp, has_threshold;
    pn_render_settings settings;
    double snapshot_percents[64]; /* progressive drivers (issue 6) */
} render_options;

static const char *integrator_name(pn_integrator_kind kind) {
    switch (kind) {
    case PN_INTEGRATOR_DEFAULT:
    case PN_INTEGRATOR_REFERENCE:
        return "reference";
    case PN_INTEGRATOR_IAS:
        return "ias";
    /* VPL integrators (issue 5) */
    case PN_INTEGRATOR_VPL:
        return "vpl";
    case PN_INTEGRATOR_LIGHTCUTS:
        return "lightcuts";
    case PN_INTEGRATOR_ILLUMCUT:
        return "illumcut";
    case PN_INTEGRATOR_CONTOUR:
        return "contour";
    case PN_INTEGRATOR_CONTOUR_MC:
        return "contour-mc";
    }
    return "unknown";
}

/* Parses the arguments of `render`. Returns -1 to continue, or an exit code. */
static int parse_render_args(int argc, char **argv, render_options *o) {
    const char *cmd = "render";
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    const char *positional = NULL, *value;
    int kind;
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (o->scene_path)
                return usage_error(cmd, "unexpected argument '%s'", positional);
            o->scene_path = positional;
            continue;
        }
        const char *name = s.name;
        if (strcmp(name, "-h") == 0 || strcmp(name, "--help") == 0) {
            fputs(render_help, stdout);
            return EXIT_OK;
        } else if (strcmp(name, "--quiet") == 0 || strcmp(name, "-q") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            o->quiet = 1;
        } else if (strcmp(name, "-o") == 0 || strcmp(name, "--output") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!is_writable_image_name(value))
                return bad_value(cmd, name, value, "a file name ending in .exr, .pfm or .png");
            o->output_path = value;
        } else if (strcmp(name, "--aov-png") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            o->aov_png = 1;
        } else if (strcmp(name, "--png") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!ends_with(value, ".png"))
                return bad_value(cmd, name, value, "a file name ending in .png");
            o->png_path = value;
        } else if (strcmp(name, "--stats") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (value[0] == '\0')
                return bad_value(cmd, name, value, "a file name");
            o->stats_path = value;
        } else if (strcmp(name, "--exposure") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &o->exposure) || fabs(o->exposure) > 64.0)
                return bad_value(cmd, name, value, "a number of stops between -64 and 64");
        } else if (strcmp(name, "--integrator") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (strcmp(value, "reference") == 0)
                o->settings.integrator = PN_INTEGRATOR_REFERENCE;
            else if (strcmp(value, "ias") == 0)
                o->settings.integrator = PN_INTEGRATOR_IAS;
            else if (strcmp(value, "vpl") == 0) /* VPL integrators (issue 5) */
                o->settings.integrator = PN_INTEGRATOR_VPL;
            else if (strcmp(value, "lightcuts") == 0)
                o->settings.integrator = PN_INTEGRATOR_LIGHTCUTS;
            else if (strcmp(value, "illumcut") == 0)
                o->settings.integrator = PN_INTEGRATOR_ILLUMCUT;
            else if (strcmp(value, "contour") == 0)
                o->settings.integrator = PN_INTEGRATOR_CONTOUR;
            else if (strcmp(value, "contour-mc") == 0)
                o->settings.integrator = PN_INTEGRATOR_CONTOUR_MC;
            else
                return bad_value(cmd, name, value,
                                 "'reference' or 'ias' (or 'contour', 'contour-mc', 'vpl', 'lightcuts', 'illumcut')");
        } else if (strcmp(name, "--light-sampler") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (strcmp(value, "irradiance") == 0)
                o->settings.light_sampler = PN_LIGHT_SAMPLER_IRRADIANCE;
            else if (strcmp(value, "bvh") == 0)
                o->settings.light_sampler = PN_LIGHT_SAMPLER_BVH;
            else
                return bad_value(cmd, name, value, "'irradiance' or 'bvh'");
        } else if (strcmp(name, "--cluster-solid-angle") == 0) {
            double v;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &v) || !(v > 0.0) || v > 12.6)
                return bad_value(cmd, name, value, "a solid angle in steradians, > 0 and <= 4 pi");
            o->settings.cluster_solid_angle = (float)v;
        } else if (strcmp(name, "--aa-rays") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 4096, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 4096");
            o->settings.aa_rays = (uint32_t)n;
        } else if (strcmp(name, "--env-regions") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 100000, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 100000");
            o->settings.env_regions = (uint32_t)n;
        } else if (strcmp(name, "--block-size") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 8, 32, &n))
                return bad_value(cmd, name, value, "an integer from 8 to 32");
            o->settings.block_size = (uint32_t)n;
        } else if (strcmp(name, "--max-passes") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 64, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 64");
            o->settings.max_passes = (uint32_t)n;
        /* VPL integrators (issue 5): vpl, lightcuts, illumcut */
        } else if (strcmp(name, "--vpls") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 100000000, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 100000000");
            o->settings.vpls = (uint32_t)n;
        } else if (strcmp(name, "--vpl-depth") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 1000, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 1000");
            o->settings.vpl_max_depth = (uint32_t)n;
        } else if (strcmp(name, "--vpl-clamp") == 0) {
            double v;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &v) || !(v > 0.0) || !(v < 1.0))
                return bad_value(cmd, name, value, "a fraction of the scene radius, > 0 and < 1");
            o->settings.vpl_clamp_fraction = (float)v;
        } else if (strcmp(name, "--vpl-direct-only") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            o->settings.vpl_direct_only = 1;
        } else if (strcmp(name, "--error") == 0) {
            double v;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &v) || !(v > 0.0) || !(v < 1.0))
                return bad_value(cmd, name, value, "a relative error, > 0 and < 1 (e.g. 0.01)");
            o->settings.error_bound = (float)v;
        } else if (strcmp(name, "--max-cut") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 100000000, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 100000000");
            o->settings.max_cut = (uint32_t)n;
        } else if (strcmp(name, "--visibility") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (strcmp(value, "sampling") == 0)
                o->settings.visibility_sampling = 1;
            else if (strcmp(value, "exact") == 0)
                o->settings.visibility_sampling = 0;
            else
                return bad_value(cmd, name, value, "'exact' or 'sampling'");
        /* contour / contour-mc options */
        } else if (strcmp(name, "--contour-grid") == 0 || strcmp(name, "--contour-steps") == 0 ||
                   strcmp(name, "--contour-span") == 0 || strcmp(name, "--mc-max-rays") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (strcmp(name, "--contour-grid") == 0) {
                if (!parse_long(value, 2, 65, &n))
                    return bad_value(cmd, name, value, "an integer from 2 to 65");
                o->settings.contour_grid = (uint32_t)n;
            } else if (strcmp(name, "--contour-steps") == 0) {
                if (!parse_long(value, 1, 12, &n))
                    return bad_value(cmd, name, value, "an integer from 1 to 12");
                o->settings.contour_steps = (uint32_t)n;
            } else if (strcmp(name, "--contour-span") == 0) {
                if (!parse_long(value, 1, 64, &n))
                    return bad_value(cmd, name, value, "an integer from 1 to 64");
                o->settings.contour_span = (uint32_t)n;
            } else {
                if (!parse_long(value, 4, 1 << 20, &n))
                    return bad_value(cmd, name, value, "an integer from 4 to 1048576");
                o->settings.contour_mc_max_rays = (uint32_t)n;
            }
        } else if (strcmp(name, "--mc-threshold") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &o->settings.contour_mc_threshold) || !(o->settings.contour_mc_threshold > 0.0))
                return bad_value(cmd, name, value, "a finite number > 0");
        } else if (strcmp(name, "--contour-off") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            const char *p = value;
            while (*p) {
                size_t len = strcspn(p, ",");
                if (len == 5 && strncmp(p, "shaft", 5) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_SHAFT_CULLING;
                else if (len == 5 && strncmp(p, "spans", 5) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_SPANS;
                else if (len == 8 && strncmp(p, "validity", 8) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_VALIDITY;
                else if (len == 8 && strncmp(p, "adaptive", 8) == 0)
                    o->settings.contour_flags |= PN_CONTOUR_NO_ADAPTIVE_DENSITY;
                else if (len == 8 && strncmp(p, "restarts", 8) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_RESTARTS;
                else if (len == 7 && strncmp(p, "islands", 7) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_ISLANDS;
                else if (len == 4 && strncmp(p, "half", 4) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_HALF_CHECK;
                else if (len == 6 && strncmp(p, "scouts", 6) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_SCOUTS;
                else if (len == 6 && strncmp(p, "linear", 6) == 0) o->settings.contour_flags |= PN_CONTOUR_NO_LINEAR_RUNS;
                else
                    return bad_value(cmd, name, value,
                                     "a comma-separated list of shaft, spans, validity, adaptive, restarts, islands, "
                                     "half, scouts, linear");
                p += len;
                if (*p == ',') p++;
            }
        } else if (strcmp(name, "--spp") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, UINT32_MAX, &n))
                return bad_value(cmd, name, value, "an integer >= 1");
            o->settings.spp = (uint32_t)n;
            o->has_spp = 1;
        } else if (strcmp(name, "--threshold") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_double(value, &o->settings.threshold) || !(o->settings.threshold > 0.0))
                return bad_value(cmd, name, value, "a finite number > 0");
            o->has_threshold = 1;
        } else if (strcmp(name, "--shadow-rays") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 65536, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 65536");
            o->settings.shadow_rays = (uint32_t)n;
        } else if (strcmp(name, "--max-samples") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, UINT32_MAX, &n))
                return bad_value(cmd, name, value, "an integer >= 1");
            o->settings.max_shadow_rays = (uint32_t)n;
        } else if (strcmp(name, "--resolution") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_resolution(value, &o->settings.width, &o->settings.height))
                return bad_value(cmd, name, value, "WxH with each side from 1 to 65536");
        } else if (strcmp(name, "--crop") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_crop(value, o->settings.crop))
                return bad_value(cmd, name, value,
                                 "x0,x1,y0,y1 with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1");
            o->settings.has_crop = 1;
        } else if (strcmp(name, "--threads") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 0, 65536, &n))
                return bad_value(cmd, name, value, "an integer >= 0 (0 = all cores)");
            o->settings.threads = (int)n;
        } else if (strcmp(name, "--seed") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_u64(value, &o->settings.seed))
                return bad_value(cmd, name, value, "an unsigned 64-bit integer");
        } else if (strcmp(name, "--aov") == 0 || strcmp(name, "--aovs") == 0) {
            char bad[64];
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_aovs(value, &o->settings.aovs, bad, sizeof bad))
                return usage_error(cmd,
                                   "unknown AOV '%s' in %s: expected shadow_rays, eye_rays, "
                                   "relative_variance, depth, normal, albedo or all",
                                   bad, name);
        } else if (strcmp(name, "--driver") == 0) { /* progressive drivers (issue 6) */
            static const char *const drivers[] = {"tiles", "full", "dcm", "painter", "uniform"};
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            int found = -1;
            for (int i = 0; i < 5; i++)
                if (strcmp(value, drivers[i]) == 0) found = i;
            if (found < 0)
                return bad_value(cmd, name, value, "tiles, full, dcm, painter or uniform");
            o->settings.driver = (pn_driver_kind)found;
        } else if (strcmp(name, "--work-scale") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 16, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 16");
            o->settings.work_scale = (int)n;
        } else if (strcmp(name, "--snapshots") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            int count = 0;
            const char *cursor = value;
            for (;;) {
                char item[64];
                const char *comma = strchr(cursor, ',');
                size_t len = comma ? (size_t)(comma - cursor) : strlen(cursor);
                double v;
                snprintf(item, sizeof item, "%.*s", (int)(len < 63 ? len : 63), cursor);
                if (len == 0 || len > 63 || count == 64 || !parse_double(item, &v) || !(v > 0.0 && v <= 100.0))
                    return bad_value(cmd, name, value, "a comma-separated list of percentages in (0, 100]");
                o->snapshot_percents[count++] = v;
                if (!comma) break;
                cursor = comma + 1;
            }
            o->settings.snapshot_percents = o->snapshot_percents;
            o->settings.snapshot_percent_count = count;
        } else if (strcmp(name, "--primary-grid") == 0) {
            long n;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!parse_long(value, 1, 8, &n))
                return bad_value(cmd, name, value, "an integer from 1 to 8");
            o->settings.primary_grid = (int)n;
        } else if (strcmp(name, "--raw-radiance") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            o->settings.raw_radiance = 1;
        } else if (strcmp(name, "--no-light-guide") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            o->settings.no_light_guide = 1;
        } else if (strcmp(name, "--snapshot-every") == 0 || strcmp(name, "--stop-at") == 0) {
            double v;
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            int every = strcmp(name, "--snapshot-every") == 0;
            if (!parse_double(value, &v) || !(v > 0.0) || (!every && v > 100.0))
                return bad_value(cmd, name, value, every ? "a positive number of seconds" : "a percentage in (0, 100]");
            if (every) o->settings.snapshot_every_seconds = v;
            else o->settings.stop_percent = v;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    { /* progressive drivers (issue 6): options and AOVs that need one */
        const uint32_t mine = PN_AOV_SAMPLING_PATTERN | PN_AOV_BLOCK_MAP | PN_AOV_BLOCK_DIRECTION;
        uint32_t all = 0;
        for (size_t i = 0; i < AOV_NAME_COUNT; i++) all |= aov_names[i].bit;
        int progressive = o->settings.driver != PN_DRIVER_DEFAULT;
        if (o->settings.aovs == all) o->settings.aovs = progressive ? mine : all & ~mine;
        if (progressive && (o->settings.aovs & ~mine))
            return usage_error(cmd, "with --driver only the AOVs sampling_pattern, block_map and block_direction exist");
        if (!progressive && (o->settings.aovs & mine))
            return usage_error(cmd, "the AOVs sampling_pattern, block_map and block_direction need --driver");
        if (!progressive && (o->settings.work_scale || o->settings.snapshot_percent_count ||
                             o->settings.snapshot_every_seconds > 0.0 || o->settings.stop_percent > 0.0 ||
                             o->settings.raw_radiance || o->settings.no_light_guide || o->settings.primary_grid))
            return usage_error(cmd, "--work-scale, --snapshots, --snapshot-every, --stop-at, --raw-radiance, "
                                    "--no-light-guide and --primary-grid need --driver");
    }
    if (o->scene_path == NULL)
        return usage_error(cmd, "missing the scene file");
    if (o->has_spp && o->has_threshold)
        return usage_error(cmd, "--spp and --threshold exclude each other");
    if (o->settings.vpl_direct_only && o->settings.vpl_max_depth > 0)
        return usage_error(cmd, "--vpl-direct-only and --vpl-depth exclude each other");
    if (o->settings.light_sampler != PN_LIGHT_SAMPLER_DEFAULT && o->settings.integrator != PN_INTEGRATOR_DEFAULT &&
        o->settings.integrator != PN_INTEGRATOR_REFERENCE)
        return usage_error(cmd, "--light-sampler applies to the reference integrator only");
    if (o->has_spp && o->settings.integrator == PN_INTEGRATOR_IAS)
        return usage_error(cmd, "--spp does not apply to ias (it samples until --threshold; see --aa-rays)");
    if (o->settings.aovs && o->output_path && !ends_with(o->output_path, ".exr"))
        return usage_error(cmd, "--aov needs an .exr output (got '%s')", o->output_path);
    return -1;
}

static void write_aov_list(json_writer *w, uint32_t bits) {
    json_begin_inline_array(w, "aovs");
    for (size_t i = 0; i < AOV_NAME_COUNT; i++)
        if (bits & aov_names[i].bit)
            json_string(w, NULL, aov_names[i].name);
    json_end_array(w);
}

static void write_scene_info_json(json_writer *w, const pn_scene_info *info, pn_scene scene) {
    json_begin_object(w, "scene_info");
    json_u64(w, "triangles", info->triangles);
    json_u64(w, "unique_triangles", info->unique_triangles);
    json_u64(w, "meshes", info->meshes);
    json_u64(w, "instances", info->instances);
    json_u64(w, "spheres", info->spheres);
    json_begin_object(w, "lights");
    json_u64(w, "point", info->lights_point);
    json_u64(w, "spot", info->lights_spot);
    json_u64(w, "distant", info->lights_distant);
    json_u64(w, "infinite", info->lights_infinite);
    json_u64(w, "goniometric", info->lights_goniometric);
    json_u64(w, "area_triangle", info->lights_area_triangle);
    json_u64(w, "area_rectangle", info->lights_area_rectangle);
    json_u64(w, "area_disk", info->lights_area_disk);
    json_u64(w, "area_sphere", info->lights_area_sphere);
    json_end_object(w);
    json_u64(w, "materials", info->materials);
    json_u64(w, "textures", info->textures);
    json_u64(w, "warnings", info->warnings);
    json_begin_inline_array(w, "bounds_min");
    for (int i = 0; i < 3; i++)
        json_double(w, NULL, (double)info->bounds_min[i]);
    json_end_array(w);
    json_begin_inline_array(w, "bounds_max");
    for (int i = 0; i < 3; i++)
        json_double(w, NULL, (double)info->bounds_max[i]);
    json_end_array(w);
    json_begin_inline_array(w, "film_resolution");
    json_int(w, NULL, info->resolution[0]);
    json_int(w, NULL, info->resolution[1]);
    json_end_array(w);
    json_double(w, "parse_seconds", info->parse_seconds);
    json_double(w, "bvh_seconds", info->bvh_seconds);
    json_begin_array(w, "material_mapping");
    uint32_t count = pn_scene_material_count(scene);
    for (uint32_t i = 0; i < count; i++)
        json_string(w, NULL, pn_scene_material_description(scene, i));
    json_end_array(w);
    json_end_object(w);
}

/* Writes the --stats JSON atomically. Returns an exit code. */
static int write_stats_json(const render_options *o, const char *image_path, pn_scene scene,
                            const pn_scene_info *info, const pn_render_stats *stats,
                            int interrupted_render) {
    char *tmp_path = NULL;
    FILE *file = atomic_open(o->stats_path, &tmp_path);
    if (file == NULL) {
        fprintf(stderr, "penumbra: cannot write '%s': %s\n", o->stats_path, strerror(errno));
        free(tmp_path);
        return EXIT_SYSTEM;
    }
    json_writer w = {file, 0, {0}, {0}, 0};
    const pn_render_settings *st = &o->settings;

    json_begin_object(&w, NULL);
    json_string(&w, "penumbra_version", pn_version_string());
    json_string(&w, "scene", o->scene_path);
    json_string(&w, "image", image_path);
    json_string(&w, "png", o->png_path);
    json_bool(&w, "interrupted", interrupted_render);

    json_begin_object(&w, "settings");
    json_string(&w, "integrator", integrator_name(st->integrator));
    if (st->integrator != PN_INTEGRATOR_IAS)
        json_string(&w, "light_sampler", st->light_sampler == PN_LIGHT_SAMPLER_BVH ? "bvh" : "irradiance");
    if (st->spp) {
        json_u64(&w, "spp", st->spp);
        json_null(&w, "threshold");
    } else {
        json_null(&w, "spp");
        json_double(&w, "threshold", st->threshold);
    }
    json_u64(&w, "shadow_rays", st->shadow_rays);
    json_u64(&w, "max_shadow_rays", st->max_shadow_rays);
    if (st->width) {
        json_begin_inline_array(&w, "resolution");
        json_int(&w, NULL, st->width);
        json_int(&w, NULL, st->height);
        json_end_array(&w);
    } else {
        json_null(&w, "resolution");
    }
    if (st->has_crop) {
        json_begin_inline_array(&w, "crop");
        for (int i = 0; i < 4; i++)
            json_double(&w, NULL, (double)st->crop[i]);
        json_end_array(&w);
    } else {
        json_null(&w, "crop");
    }
    json_int(&w, "threads", st->threads);
    json_u64(&w, "seed", st->seed);
    write_aov_list(&w, st->aovs);
    json_double(&w, "exposure", o->exposure);
    json_end_object(&w);

    json_begin_object(&w, "stats");
    json_int(&w, "width", stats->width);
    json_int(&w, "height", stats->height);
    json_int(&w, "threads", stats->threads);
    json_double(&w, "parse_seconds", info->parse_seconds);
    json_double(&w, "bvh_seconds", info->bvh_seconds);
    json_double(&w, "render_seconds", stats->render_seconds);
    json_double(&w, "embree_seconds_estimate", stats->embree_seconds_estimate);
    json_u64(&w, "eye_rays", stats->eye_rays);
    json_u64(&w, "shadow_rays", stats->shadow_rays);
    json_u64(&w, "specular_rays", stats->specular_rays);
    json_double(&w, "eye_rays_per_pixel_mean", stats->eye_rays_per_pixel_mean);
    json_u64(&w, "eye_rays_per_pixel_max", stats->eye_rays_per_pixel_max);
    json_double(&w, "shadow_rays_per_pixel_mean", stats->shadow_rays_per_pixel_mean);
    json_u64(&w, "shadow_rays_per_pixel_max", stats->shadow_rays_per_pixel_max);
    json_double(&w, "mrays_per_second", stats->mrays_per_second);
    json_u64(&w, "peak_memory_bytes", stats->peak_memory_bytes);
    json_bool(&w, "partial", stats->partial);
    if (o->settings.driver != PN_DRIVER_DEFAULT) { /* progressive drivers (issue 6) */
        static const char *const drivers[] = {"tiles", "full", "dcm", "painter", "uniform"};
        json_string(&w, "driver", drivers[o->settings.driver]);
        json_int(&w, "work_width", stats->work_width);
        json_int(&w, "work_height", stats->work_height);
        json_u64(&w, "evaluated_pixels", stats->evaluated_pixels);
        json_double(&w, "evaluated_percent", stats->evaluated_percent);
        json_u64(&w, "dcm_simple_blocks", stats->dcm_simple_blocks);
        json_u64(&w, "dcm_complex_blocks", stats->dcm_complex_blocks);
        json_u64(&w, "dcm_lazy_blocks", stats->dcm_lazy_blocks);
        json_double(&w, "primary_buffer_seconds", stats->primary_buffer_seconds);
        json_u64(&w, "primary_grid_pixels", stats->primary_grid_pixels);
        json_double(&w, "reconstruct_seconds_max", stats->reconstruct_seconds_max);
    }
    if (o->settings.integrator == PN_INTEGRATOR_IAS) {
        /* The paper's Tables 4-6: per-pixel means, and visibility per viewpoint and per pixel. */
        json_double(&w, "passes_per_pixel_mean", stats->passes_per_pixel_mean);
        json_double(&w, "aa_regions_per_pixel_mean", stats->aa_regions_per_pixel_mean);
        json_double(&w, "clusters_per_point_mean", stats->clusters_per_point_mean);
        json_double(&w, "visible_fraction_mean", stats->visible_fraction_mean);
        json_u64(&w, "lights_visible_viewpoint", stats->lights_visible_viewpoint);
        json_u64(&w, "env_regions_visible_viewpoint", stats->env_regions_visible_viewpoint);
        json_double(&w, "visible_lights_per_pixel_mean", stats->visible_lights_per_pixel_mean);
        json_double(&w, "cut_seconds_estimate", stats->cut_seconds_estimate);
        json_double(&w, "pdf_seconds_estimate", stats->pdf_seconds_estimate);
    }
    if (o->settings.integrator == PN_INTEGRATOR_VPL || o->settings.integrator == PN_INTEGRATOR_LIGHTCUTS ||
        o->settings.integrator == PN_INTEGRATOR_ILLUMCUT) {
        /* VPL integrators (issue 5): IlluminationCut Table 1's rows. */
        json_double(&w, "preprocess_seconds", stats->preprocess_seconds);
        json_double(&w, "vpl_seconds", stats->vpl_seconds);
        json_double(&w, "light_tree_seconds", stats->light_tree_seconds);
        json_u64(&w, "vpl_count", stats->vpl_count);
        json_u64(&w, "vpl_paths", stats->vpl_paths);
        json_double(&w, "bound_evaluations_per_pixel_mean", stats->bound_evaluations_per_pixel_mean);
        json_double(&w, "cut_size_mean", stats->cut_size_mean);
        json_double(&w, "point_tree_seconds", stats->point_tree_seconds);
        json_double(&w, "phase1_seconds", stats->phase1_seconds);
        json_double(&w, "phase2_seconds", stats->phase2_seconds);
        json_u64(&w, "illumcut_pairs", stats->illumcut_pairs);
    }
    if (o->settings.integrator == PN_INTEGRATOR_CONTOUR || o->settings.integrator == PN_INTEGRATOR_CONTOUR_MC) {
        /* Vedel 1993, Table 1: shadow rays per viewing ray that cast any (towards contour sources). */
        json_u64(&w, "contour_viewing_rays", stats->contour_viewing_rays);
        json_u64(&w, "contour_shadow_rays", stats->contour_shadow_rays);
        json_double(&w, "contour_shadow_rays_per_viewing_ray",
                    stats->contour_viewing_rays
                        ? (double)stats->contour_shadow_rays / (double)stats->contour_viewing_rays : 0.0);
        json_u64(&w, "contour_integrations", stats->contour_integrations);
        json_u64(&w, "contour_interpolated", stats->contour_interpolated);
        json_u64(&w, "contour_restarts", stats->contour_restarts);
        json_u64(&w, "contour_subdivisions", stats->contour_subdivisions);
        json_u64(&w, "contour_culled_spans", stats->contour_culled_spans);
    }
    json_end_object(&w);

    write_scene_info_json(&w, info, scene);
    json_end_object(&w);
    fputc('\n', file);

    int error = atomic_commit(file, tmp_path, o->stats_path);
    free(tmp_path);
    if (error) {
        fprintf(stderr, "penumbra: cannot write '%s': %s\n", o->stats_path, strerror(error));
        return EXIT_SYSTEM;
    }
    return EXIT_OK;
}

static void print_count(const char *label, uint64_t value) {
    printf("%-14s %llu\n", label, (unsigned long long)value);
}

static void print_render_summary(const render_options *o, const pn_scene_info *info,
                                 const pn_render_stats *stats, const char *image_path) {
    printf("scene          %s\n", o->scene_path);
    printf("resolution     %dx%d", stats->width, stats->height);
    if (o->settings.has_crop)
        printf(" (crop %g,%g,%g,%g)", (double)o->settings.crop[0], (double)o->settings.crop[1],
               (double)o->settings.crop[2], (double)o->settings.crop[3]);
    printf("\n");
    if (o->settings.spp)
        printf("sampling       %u eye rays/pixel, %u shadow rays/eye ray\n", o->settings.spp,
               o->settings.shadow_rays);
    else
        printf("sampling       adaptive, threshold %g, %u shadow rays/eye ray, at most %u/pixel\n",
               o->settings.threshold, o->settings.shadow_rays, o->settings.max_shadow_rays);
    printf("time           parse %.2f s, BVH %.2f s, render %.2f s (%d threads)\n",
           info->parse_seconds, info->bvh_seconds, stats->render_seconds, stats->threads);
    print_count("eye rays", stats->eye_rays);
    print_count("shadow rays", stats->shadow_rays);
    print_count("specular rays", stats->specular_rays);
    printf("eye/pixel      mean %.2f, max %llu\n", stats->eye_rays_per_pixel_mean,
           (unsigned long long)stats->eye_rays_per_pixel_max);
    printf("shadow/pixel   mean %.1f, max %llu\n", stats->shadow_rays_per_pixel_mean,
           (unsigned long long)stats->shadow_rays_per_pixel_max);
    printf("speed          %.2f Mrays/s\n", stats->mrays_per_second);
    if (stats->vpl_count) /* VPL integrators (issue 5) */
        printf("VPLs           %llu (%llu paths), preprocessing %.2f s (VPLs %.2f s, light tree %.2f s), "
               "bounds/pixel %.1f\n", (unsigned long long)stats->vpl_count, (unsigned long long)stats->vpl_paths,
               stats->preprocess_seconds, stats->vpl_seconds, stats->light_tree_seconds,
               stats->bound_evaluations_per_pixel_mean);
    printf("peak memory    %.1f MiB\n", (double)stats->peak_memory_bytes / (1024.0 * 1024.0));
    printf("wrote          %s", image_path);
    if (o->png_path)
        printf(", %s", o->png_path);
    if (o->stats_path)
        printf(", %s", o->stats_path);
    printf("\n");
}

/* --aov-png: every single-channel AOV layer as a false-colour PNG with a colour bar, named
 * after the output image: out.exr -> out.passes.png, out.shadow_rays.png, ... */
/* Progressive drivers (issue 6): snapshots beside the output (out.exr -> out-6pct.exr), written
 * atomically by pn_image_write; SIGUSR1 asks for one. */
typedef struct snapshot_writer {
    const char *image_path, *png_path;
    double exposure;
    int quiet;
} snapshot_writer;

static void snapshot_name(const char *path, double percent, char *out, size_t size) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (!dot || (slash && dot < slash)) dot = path + strlen(path);
    snprintf(out, size, "%.*s-%gpct%s", (int)(dot - path), path, percent, dot);
}

static void on_snapshot(void *user, pn_image image, double requested, double evaluated, double seconds) {
    const snapshot_writer *sw = user;
    double percent = requested > 0.0 ? requested : floor(evaluated * 10.0 + 0.5) / 10.0;
    pn_context wctx = pn_context_new();
    if (!wctx) return;
    for (int i = 0; i < 2; i++) {
        const char *base = i == 0 ? sw->image_path : sw->png_path;
        if (!base) continue;
        char path[4096];
        snapshot_name(base, percent, path, sizeof path);
        if (pn_image_write(wctx, image, path, (float)sw->exposure) != PN_OK)
            fprintf(stderr, "penumbra: cannot write snapshot: %s\n", pn_context_error_message(wctx));
        else if (!sw->quiet)
            fprintf(stderr, "penumbra: snapshot %s (%.2f%% of the work pixels, %.2f s)\n", path, evaluated, seconds);
    }
    pn_context_free(wctx);
}

static void on_sigusr1(int signo) {
    (void)signo;
    if (interrupt_context)
        pn_render_request_snapshot(interrupt_context);
}

static int write_aov_pngs(pn_context ctx, pn_image image, const char *image_path) {
    const char *dot = strrchr(image_path, '.');
    size_t stem = dot ? (size_t)(dot - image_path) : strlen(image_path);
    for (int l = 1; l < pn_image_layer_count(image); l++) {
        if (pn_image_layer_channels(image, l) != 1) continue;
        const char *name = pn_image_layer_name(image, l);
        char path[4096];
        snprintf(path, sizeof path, "%.*s.%s.png", (int)stem, image_path, name);
        pn_image fc = NULL;
        pn_status st = pn_image_false_color(ctx, image, name, 0.0, 0.0, &fc);
        if (st == PN_OK) st = pn_image_write(ctx, fc, path, 0.0f);
        pn_image_free(fc);
        if (st != PN_OK) return report_failure(ctx, st);
    }
    return EXIT_OK;
}

static int command_render(int argc, char **argv) {
    render_options o;
    memset(&o, 0, sizeof o);
    int code = parse_render_args(argc, argv, &o);
    if (code >= 0)
        return code;

    pn_render_settings *st = &o.settings;
    if (st->integrator == PN_INTEGRATOR_DEFAULT)
        st->integrator = PN_INTEGRATOR_REFERENCE;
    if (!o.has_spp && !o.has_threshold)
        st->threshold = CLI_DEFAULT_THRESHOLD;
    if (st->shadow_rays == 0)
        st->shadow_rays = CLI_DEFAULT_SHADOW_RAYS;
    if (st->max_shadow_rays == 0)
        st->max_shadow_rays = CLI_DEFAULT_MAX_SHADOW_RAYS;

    char *default_name = NULL;
    const char *image_path = o.output_path;
    if (image_path == NULL) {
        default_name = default_output_name(o.scene_path);
        if (default_name == NULL) {
            fprintf(stderr, "penumbra: out of memory\n");
            return EXIT_SYSTEM;
        }
        image_path = default_name;
    }

    /* Refuse early when an output folder is missing, rather than after the render. */
    if ((code = check_output_folder(image_path)) != EXIT_OK ||
        (o.png_path && (code = check_output_folder(o.png_path)) != EXIT_OK) ||
        (o.stats_path && (code = check_output_folder(o.stats_path)) != EXIT_OK)) {
        free(default_name);
        return code;
    }

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        free(default_name);
        return EXIT_SYSTEM;
    }
    log_options log = {o.quiet, 1};
    pn_context_set_log(ctx, on_log, &log);

    pn_scene scene = NULL;
    pn_image image = NULL;
    pn_scene_info info;
    pn_render_stats stats;
    memset(&info, 0, sizeof info);
    memset(&stats, 0, sizeof stats);
    pn_status status = pn_scene_load(ctx, o.scene_path, &scene);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if ((status = pn_scene_get_info(scene, &info)) != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }

    progress_state progress = {monotonic_seconds(), 0.0, 0};
    if (!o.quiet && isatty(STDERR_FILENO)) {
        st->progress = on_progress;
        st->progress_user = &progress;
    }

    struct sigaction action, previous;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_sigint;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESETHAND; /* a second Ctrl-C ends the program at once */
    interrupt_context = ctx;
    interrupted = 0;
    sigaction(SIGINT, &action, &previous);
    /* progressive drivers (issue 6): snapshots, and SIGUSR1 for one now */
    snapshot_writer snapshots = {image_path, o.png_path, o.exposure, o.quiet};
    struct sigaction usr1, previous_usr1;
    memset(&usr1, 0, sizeof usr1);
    usr1.sa_handler = on_sigusr1;
    sigemptyset(&usr1.sa_mask);
    if (st->driver != PN_DRIVER_DEFAULT) {
        st->snapshot = on_snapshot;
        st->snapshot_user = &snapshots;
        sigaction(SIGUSR1, &usr1, &previous_usr1);
    }
    status = pn_render(ctx, scene, st, &image, &stats);
    if (st->driver != PN_DRIVER_DEFAULT)
        sigaction(SIGUSR1, &previous_usr1, NULL);
    sigaction(SIGINT, &previous, NULL);
    interrupt_context = NULL;
    finish_progress(&progress, status == PN_OK);

    if (status == PN_ERROR_CANCELLED || (status == PN_OK && interrupted)) {
        /* The user asked to stop: keep what was rendered, but never under the requested name,
         * where it could be mistaken for a finished image. */
        fprintf(stderr, "penumbra: interrupted; the partial image was not written to '%s'\n",
                image_path);
        char *partial_path = image ? partial_output_name(image_path) : NULL;
        int partial_written = 0;
        if (partial_path) {
            pn_context_clear_error(ctx);
            partial_written = pn_image_write(ctx, image, partial_path, (float)o.exposure) == PN_OK;
            if (partial_written)
                fprintf(stderr, "penumbra: what was rendered is in '%s'\n", partial_path);
        }
        if (o.stats_path)
            write_stats_json(&o, partial_written ? partial_path : NULL, scene, &info, &stats, 1);
        free(partial_path);
        code = EXIT_INTERRUPTED;
        goto done;
    }
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }

    /* The exposure only affects PNG files. */
    if ((status = pn_image_write(ctx, image, image_path, (float)o.exposure)) != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (o.png_path && (status = pn_image_write(ctx, image, o.png_path, (float)o.exposure)) !=
                          PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (o.aov_png && (code = write_aov_pngs(ctx, image, image_path)) != EXIT_OK)
        goto done;
    if (o.stats_path &&
        (code = write_stats_json(&o, image_path, scene, &info, &stats, 0)) != EXIT_OK)
        goto done;
    if (!o.quiet)
        print_render_summary(&o, &info, &stats, image_path);
    code = EXIT_OK;

done:
    pn_image_free(image);
    pn_scene_free(scene);
    pn_context_free(ctx);
    free(default_name);
    return code;
}

/* ---------------------------------------------------------------------------------------- */
/* diff */

static int command_diff(int argc, char **argv) {
    const char *cmd = "diff";
    const char *paths[2] = {NULL, NULL};
    const char *error_path = NULL, *positional = NULL, *value;
    int json = 0, count = 0, kind;
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (count >= 2)
                return usage_error(cmd, "unexpected argument '%s'", positional);
            paths[count++] = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(diff_help, stdout);
            return EXIT_OK;
        } else if (strcmp(s.name, "--json") == 0) {
            if (!scanner_no_value(&s))
                return EXIT_USAGE;
            json = 1;
        } else if (strcmp(s.name, "--error-image") == 0) {
            if ((value = scanner_value(&s)) == NULL)
                return EXIT_USAGE;
            if (!is_writable_image_name(value))
                return bad_value(cmd, s.name, value, "a file name ending in .exr, .pfm or .png");
            error_path = value;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    if (count < 2)
        return usage_error(cmd, "needs two images, REFERENCE and IMAGE");
    int code;
    if ((code = check_input_file(paths[0])) != EXIT_OK ||
        (code = check_input_file(paths[1])) != EXIT_OK)
        return code;
    if (error_path && (code = check_output_folder(error_path)) != EXIT_OK)
        return code;

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    log_options log = {0, 1};
    pn_context_set_log(ctx, on_log, &log);
    pn_image reference = NULL, image = NULL, error_image = NULL;
    pn_image_metrics m;
    memset(&m, 0, sizeof m);
    pn_status status = pn_image_read(ctx, paths[0], &reference);
    if (status == PN_OK)
        status = pn_image_read(ctx, paths[1], &image);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    int rw = pn_image_width(reference), rh = pn_image_height(reference);
    int iw = pn_image_width(image), ih = pn_image_height(image);
    if (rw != iw || rh != ih) {
        fprintf(stderr, "penumbra: image sizes differ: '%s' is %dx%d, '%s' is %dx%d\n", paths[0],
                rw, rh, paths[1], iw, ih);
        code = EXIT_BAD_INPUT;
        goto done;
    }
    status = pn_image_compare(ctx, reference, image, &m, error_path ? &error_image : NULL);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (error_path && (status = pn_image_write(ctx, error_image, error_path, 0.0f)) != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }
    if (json) {
        json_writer w = {stdout, 0, {0}, {0}, 0};
        json_begin_object(&w, NULL);
        json_string(&w, "reference", paths[0]);
        json_string(&w, "image", paths[1]);
        json_int(&w, "width", rw);
        json_int(&w, "height", rh);
        json_double(&w, "rmse", m.rmse);
        json_double(&w, "relmse", m.relmse);
        json_double(&w, "relmse_epsilon", m.relmse_epsilon);
        json_double(&w, "rel_l1", m.rel_l1);
        json_double(&w, "rel_l2", m.rel_l2);
        json_double(&w, "mae", m.mae);
        json_double(&w, "mean_luminance_reference", m.mean_luminance_reference);
        json_double(&w, "mean_luminance_image", m.mean_luminance_image);
        json_string(&w, "error_image", error_path);
        json_end_object(&w);
        fputc('\n', stdout);
    } else {
        printf("reference      %s (%dx%d)\n", paths[0], rw, rh);
        printf("image          %s\n", paths[1]);
        printf("RMSE           %.6g\n", m.rmse);
        printf("relMSE         %.6g (epsilon %g)\n", m.relmse, m.relmse_epsilon);
        printf("rel L1         %.6g\n", m.rel_l1);
        printf("rel L2         %.6g\n", m.rel_l2);
        printf("MAE            %.6g\n", m.mae);
        printf("mean luminance reference %.6g, image %.6g\n", m.mean_luminance_reference,
               m.mean_luminance_image);
        if (error_path)
            printf("error image    %s (|image - reference| x 16)\n", error_path);
    }
    code = EXIT_OK;

done:
    pn_image_free(error_image);
    pn_image_free(image);
    pn_image_free(reference);
    pn_context_free(ctx);
    return code;
}

/* ---------------------------------------------------------------------------------------- */
/* info */

static int command_info(int argc, char **argv) {
    const char *cmd = "info";
    const char *scene_path = NULL, *positional = NULL;
    int kind;
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (scene_path)
                return usage_error(cmd, "unexpected argument '%s'", positional);
            scene_path = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(info_help, stdout);
            return EXIT_OK;
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    if (scene_path == NULL)
        return usage_error(cmd, "missing the scene file");

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    /* Warnings are listed in the report, so the log need not print them too. */
    log_options log = {1, 0};
    pn_context_set_log(ctx, on_log, &log);
    pn_scene scene = NULL;
    pn_scene_info info;
    memset(&info, 0, sizeof info);
    int code;
    pn_status status = pn_scene_load(ctx, scene_path, &scene);
    if (status == PN_OK)
        status = pn_scene_get_info(scene, &info);
    if (status != PN_OK) {
        code = report_failure(ctx, status);
        goto done;
    }

    uint64_t area = (uint64_t)info.lights_area_triangle + info.lights_area_rectangle +
                    info.lights_area_disk + info.lights_area_sphere;
    uint64_t lights = area + info.lights_point + info.lights_spot + info.lights_distant +
                      info.lights_infinite + info.lights_goniometric;
    printf("scene          %s\n", scene_path);
    printf("film           %dx%d\n", info.resolution[0], info.resolution[1]);
    printf("triangles      %llu (%llu unique)\n", (unsigned long long)info.triangles,
           (unsigned long long)info.unique_triangles);
    printf("meshes         %u\n", info.meshes);
    printf("instances      %u\n", info.instances);
    printf("spheres        %u\n", info.spheres);
    printf("lights         %llu\n", (unsigned long long)lights);
    printf("  point        %u\n", info.lights_point);
    printf("  spot         %u\n", info.lights_spot);
    printf("  distant      %u\n", info.lights_distant);
    printf("  infinite     %u\n", info.lights_infinite);
    printf("  goniometric  %u\n", info.lights_goniometric);
    printf("  area         %llu (triangle %u, rectangle %u, disk %u, sphere %u)\n",
           (unsigned long long)area, info.lights_area_triangle, info.lights_area_rectangle,
           info.lights_area_disk, info.lights_area_sphere);
    uint32_t material_count = pn_scene_material_count(scene);
    printf("materials      %u\n", info.materials);
    for (uint32_t i = 0; i < material_count; i++) {
        const char *line = pn_scene_material_description(scene, i);
        printf("  %s\n", line ? line : "");
    }
    printf("textures       %u\n", info.textures);
    printf("bounds         (%g, %g, %g) to (%g, %g, %g)\n", (double)info.bounds_min[0],
           (double)info.bounds_min[1], (double)info.bounds_min[2], (double)info.bounds_max[0],
           (double)info.bounds_max[1], (double)info.bounds_max[2]);
    printf("load time      parse %.3f s, BVH %.3f s\n", info.parse_seconds, info.bvh_seconds);
    uint32_t warning_count = pn_scene_warning_count(scene);
    printf("warnings       %u\n", warning_count);
    for (uint32_t i = 0; i < warning_count; i++) {
        const char *line = pn_scene_warning(scene, i);
        printf("  %s\n", line ? line : "");
    }
    code = EXIT_OK;

done:
    pn_scene_free(scene);
    pn_context_free(ctx);
    return code;
}

/* ---------------------------------------------------------------------------------------- */

static void print_version(void) {
    printf("penumbra %s\n", pn_version_string());
    if (strcmp(pn_version_string(), PN_VERSION_STRING) != 0)
        printf("(built against header version %s)\n", PN_VERSION_STRING);
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fputs(main_help, stderr);
        return EXIT_USAGE;
    }
    const char *command = argv[1];
    if (strcmp(command, "render") == 0)
        return command_render(argc - 1, argv + 1);
    if (strcmp(command, "diff") == 0)
        return command_diff(argc - 1, argv + 1);
    if (strcmp(command, "info") == 0)
        return command_info(argc - 1, argv + 1);
    if (strcmp(command, "--help") == 0 || strcmp(command, "-h") == 0 ||
        strcmp(command, "help") == 0) {
        if (argc >= 3 && strcmp(command, "help") == 0) {
            if (strcmp(argv[2], "render") == 0)
                fputs(render_help, stdout);
            else if (strcmp(argv[2], "diff") == 0)
                fputs(diff_help, stdout);
            else if (strcmp(argv[2], "info") == 0)
                fputs(info_help, stdout);
            else
                return usage_error(NULL, "unknown command '%s'", argv[2]);
            return EXIT_OK;
        }
        fputs(main_help, stdout);
        return EXIT_OK;
    }
    if (strcmp(command, "--version") == 0 || strcmp(command, "-V") == 0) {
        print_version();
        return EXIT_OK;
    }
    if (command[0] == '-')
        return usage_error(NULL, "unknown option '%s'", command);
    return usage_error(NULL, "unknown command '%s'", command);
}
