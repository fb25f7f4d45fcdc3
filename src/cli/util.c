/* util.c — the CLI's small helpers: usage errors and exit codes, paths, strict number parsing,
 * the argument scanner and the log callback. */
#include "cli/cli.h"

#include <stdio.h>
#include <sys/stat.h>
#include <fcntl.h>
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

/* ---------------------------------------------------------------------------------------- */
/* Small helpers */

/* Prints "penumbra COMMAND: message (see penumbra COMMAND --help)" and returns EXIT_USAGE. */
int usage_error(const char *command, const char *fmt, ...) {
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

int exit_code_for(pn_status status) {
    switch (status) {
    case PN_OK: return EXIT_OK;
    case PN_ERROR_BAD_INPUT:
    case PN_ERROR_UNSUPPORTED: return EXIT_BAD_INPUT;
    case PN_ERROR_IO:
    case PN_ERROR_OUT_OF_MEMORY: return EXIT_SYSTEM;
    case PN_ERROR_CANCELLED: return EXIT_INTERRUPTED;
    case PN_ERROR_INVALID_ARGUMENT:
        /* The CLI passes the user's values on: a combination the library refuses (e.g.
         * --vpl-direct-only with --vpl-depth, a contour grid too fine for its steps) is a usage
         * error, not a bug. */
        return EXIT_USAGE;
    default: return EXIT_INTERNAL;
    }
}

/* Reports a failed library call and returns the matching exit code. */
int report_failure(pn_context ctx, pn_status status) {
    const char *message = ctx ? pn_context_error_message(ctx) : "";
    if (message == NULL || message[0] == '\0') message = pn_status_string(status);
    fprintf(stderr, "penumbra: %s\n", message);
    return exit_code_for(status);
}

double monotonic_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int ends_with(const char *s, const char *suffix) {
    size_t n = strlen(s), m = strlen(suffix);
    if (m > n) return 0;
    for (size_t i = 0; i < m; i++) {
        char a = s[n - m + i], b = suffix[i];
        if (a >= 'A' && a <= 'Z') a = (char)(a - 'A' + 'a');
        if (a != b) return 0;
    }
    return 1;
}

/* Image formats pn_image_write understands, by extension. */
int is_writable_image_name(const char *path) {
    return ends_with(path, ".exr") || ends_with(path, ".pfm") || ends_with(path, ".png");
}

/* Fails early, before a long render, when the folder of `path` is missing or not writable. */
int check_output_folder(const char *path) {
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
int check_input_file(const char *path) {
    if (access(path, R_OK) != 0) {
        fprintf(stderr, "penumbra: %s: %s\n", path, strerror(errno));
        return EXIT_BAD_INPUT;
    }
    return EXIT_OK;
}

/* "dir/name.pbrt" -> "name.exr" (in the current folder). Caller frees. */
char *default_output_name(const char *scene_path) {
    const char *base = strrchr(scene_path, '/');
    base = base ? base + 1 : scene_path;
    size_t n = strlen(base);
    if (ends_with(base, ".pbrt")) n -= 5;
    if (n == 0) {
        base = "out";
        n = 3;
    }
    char *name = malloc(n + 5);
    if (name == NULL) return NULL;
    memcpy(name, base, n);
    memcpy(name + n, ".exr", 5);
    return name;
}

/* "out/x.exr" -> "out/x.partial.exr". Caller frees. */
char *partial_output_name(const char *path) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(path, '.');
    if (dot == NULL || (slash && dot < slash)) dot = path + strlen(path);
    size_t stem = (size_t)(dot - path);
    size_t total = strlen(path) + sizeof ".partial";
    char *name = malloc(total);
    if (name == NULL) return NULL;
    memcpy(name, path, stem);
    snprintf(name + stem, total - stem, ".partial%s", dot);
    return name;
}

/* ---------------------------------------------------------------------------------------- */
/* Strict number parsing: the whole string must be a number, no leading blanks or signs where
 * they make no sense, and the value must be in range. */

int parse_long(const char *text, long min, long max, long *out) {
    char *end = NULL;
    if (text[0] == '\0' || text[0] == ' ' || text[0] == '\t' || text[0] == '+') return 0;
    errno = 0;
    long value = strtol(text, &end, 10);
    if (errno != 0 || end == text || *end != '\0' || value < min || value > max) return 0;
    *out = value;
    return 1;
}

int parse_u64(const char *text, uint64_t *out) {
    char *end = NULL;
    if (text[0] < '0' || text[0] > '9') return 0;
    errno = 0;
    unsigned long long value = strtoull(text, &end, 10);
    if (errno != 0 || *end != '\0') return 0;
    *out = (uint64_t)value;
    return 1;
}

int parse_double(const char *text, double *out) {
    char *end = NULL;
    if (text[0] == '\0' || text[0] == ' ' || text[0] == '\t') return 0;
    errno = 0;
    double value = strtod(text, &end);
    if (errno != 0 || end == text || *end != '\0' || !isfinite(value)) return 0;
    *out = value;
    return 1;
}

/* "WxH" with each side in 1..65536. */
int parse_resolution(const char *text, int *width, int *height) {
    const char *x = strchr(text, 'x');
    char left[32];
    long w, h;
    if (x == NULL || (size_t)(x - text) >= sizeof left) return 0;
    memcpy(left, text, (size_t)(x - text));
    left[x - text] = '\0';
    if (!parse_long(left, 1, 65536, &w) || !parse_long(x + 1, 1, 65536, &h)) return 0;
    *width = (int)w;
    *height = (int)h;
    return 1;
}

/* "x0,x1,y0,y1" with 0 <= x0 < x1 <= 1 and 0 <= y0 < y1 <= 1. */
int parse_crop(const char *text, float crop[4]) {
    char buffer[256];
    double v[4];
    if (strlen(text) >= sizeof buffer) return 0;
    strcpy(buffer, text);
    char *cursor = buffer;
    for (int i = 0; i < 4; i++) {
        char *comma = strchr(cursor, ',');
        if ((i < 3) != (comma != NULL)) return 0;
        if (comma) *comma = '\0';
        if (!parse_double(cursor, &v[i]) || v[i] < 0.0 || v[i] > 1.0) return 0;
        cursor = comma ? comma + 1 : cursor;
    }
    if (!(v[0] < v[1]) || !(v[2] < v[3])) return 0;
    for (int i = 0; i < 4; i++) crop[i] = (float)v[i];
    return 1;
}

/* Advances to the next argument. Returns 0 at the end, 1 for an option (name filled), 2 for a
 * positional argument. */
int scanner_next(arg_scanner *s, const char **positional) {
    s->index++;
    if (s->index >= s->argc) return 0;
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
    if (n >= sizeof s->name) n = sizeof s->name - 1;
    memcpy(s->name, arg, n);
    s->name[n] = '\0';
    s->inline_value = equals ? equals + 1 : NULL;
    return 1;
}

/* The value of the current option, or NULL after printing a usage error. */
const char *scanner_value(arg_scanner *s) {
    if (s->inline_value) return s->inline_value;
    if (s->index + 1 >= s->argc) {
        usage_error(s->command, "option '%s' needs a value", s->name);
        return NULL;
    }
    s->index++;
    return s->argv[s->index];
}

/* Rejects "--flag=value" for options that take no value. */
int scanner_no_value(arg_scanner *s) {
    if (s->inline_value) {
        usage_error(s->command, "option '%s' takes no value", s->name);
        return 0;
    }
    return 1;
}

/* --max-image-pixels N: a whole number of pixels >= 1, set on ctx later. Returns 1, or 0 after
 * printing the usage error. */
int parse_pixel_limit(const char *command, const char *option, const char *value, uint64_t *out) {
    if (!parse_u64(value, out) || *out == 0) {
        bad_value(command, option, value, "a number of pixels >= 1 (default 268435456 = 16384 x 16384)");
        return 0;
    }
    return 1;
}

int bad_value(const char *command, const char *option, const char *value, const char *expected) {
    return usage_error(command, "invalid value '%s' for %s: expected %s", value, option, expected);
}

/* ---------------------------------------------------------------------------------------- */
/* A small JSON writer: pretty-printed, with string escaping, written to "<path>.tmp" and renamed
 * into place when complete. */

/* ---------------------------------------------------------------------------------------- */
/* Logging and Ctrl-C */

/* Warnings go to stderr; errors are reported once, by the caller, from the context message. */
void on_log(void *user, pn_log_level level, const char *message) {
    const log_options *options = user;
    if (level == PN_LOG_ERROR) return;
    if (level == PN_LOG_WARNING) {
        if (options->show_warnings) fprintf(stderr, "penumbra: warning: %s\n", message);
        return;
    }
    if (!options->quiet) fprintf(stderr, "penumbra: %s\n", message);
}

FILE *cli_open_regular(const char *path, const char *mode, const char **why) {
    /* O_NONBLOCK: a FIFO cannot block the open; the descriptor is made blocking again after. */
    *why = NULL;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        *why = strerror(errno);
        return NULL;
    }
    struct stat st;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        *why = S_ISDIR(st.st_mode) ? "is a folder, not a file" : "not a regular file";
        close(fd);
        errno = EINVAL;
        return NULL;
    }
    int flags = fcntl(fd, F_GETFL);
    if (flags >= 0) fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
    FILE *f = fdopen(fd, mode);
    if (!f) {
        *why = strerror(errno);
        close(fd);
    }
    return f;
}
