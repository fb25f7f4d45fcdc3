/* cli.h — what the files of the `penumbra` program share. The program is built on the public
 * header only: the methods, their options and help come from the library's method table
 * (pn_method_*, pn_option_*), never from a list of our own.
 *
 * Exit codes (README.md): 0 success, 2 usage, 3 bad input, 4 system error, 70 internal error,
 * 130 interrupted. */
#ifndef PN_CLI_CLI_H
#define PN_CLI_CLI_H

#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L /* sigaction, clock_gettime, isatty */
#endif

#include <penumbra/penumbra.h>

#include <stdint.h>
#include <stdio.h>

enum { EXIT_OK = 0, EXIT_USAGE = 2, EXIT_BAD_INPUT = 3, EXIT_SYSTEM = 4, EXIT_INTERNAL = 70, EXIT_INTERRUPTED = 130 };

/* util.c */
/* Prints "penumbra COMMAND: message (see penumbra COMMAND --help)" and returns EXIT_USAGE. */
int usage_error(const char *command, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
int exit_code_for(pn_status status);
/* Reports a failed library call and returns the matching exit code. */
int report_failure(pn_context ctx, pn_status status);
double monotonic_seconds(void);
int ends_with(const char *s, const char *suffix);
int is_writable_image_name(const char *path);
int check_output_folder(const char *path);
int check_input_file(const char *path);
char *default_output_name(const char *scene_path);
char *partial_output_name(const char *path);
int parse_long(const char *text, long min, long max, long *out);
int parse_u64(const char *text, uint64_t *out);
int parse_double(const char *text, double *out);
int parse_resolution(const char *text, int *width, int *height);
int parse_crop(const char *text, float crop[4]);

/* Option scanning shared by the commands. An argument "--name=value" carries its value inline;
 * otherwise the value is the next argument. */
typedef struct arg_scanner {
    const char *command;
    int argc;
    char **argv;
    int index;     /* of the current argument */
    char name[64]; /* current option name without "=value" */
    const char *inline_value;
    int options_done; /* after "--" everything is positional */
} arg_scanner;
/* Advances to the next argument. Returns 0 at the end, 1 for an option (name filled), 2 for a
 * positional argument. */
int scanner_next(arg_scanner *s, const char **positional);
/* The value of the current option, or NULL after printing a usage error. */
const char *scanner_value(arg_scanner *s);
/* Rejects "--flag=value" for options that take no value. */
int scanner_no_value(arg_scanner *s);
int bad_value(const char *command, const char *option, const char *value, const char *expected);
/* --max-image-pixels N (shared by render, diff and info): 1, or 0 after printing the usage error. */
int parse_pixel_limit(const char *command, const char *option, const char *value, uint64_t *out);
/* Help line of --max-image-pixels. */
#define MAX_IMAGE_PIXELS_HELP                                                                                          \
    "  --max-image-pixels N   refuse images (textures, environment maps, inputs) of more than N\n"                     \
    "                         pixels before decoding them (default 268435456 = 16384 x 16384)\n"

typedef struct log_options {
    int quiet;
    int show_warnings;
} log_options;
/* Warnings go to stderr; errors are reported once, by the caller, from the context message. */
void on_log(void *user, pn_log_level level, const char *message);

/* options.c: `penumbra render`'s arguments, its help and `penumbra methods`, from the table. */
typedef struct render_options {
    const char *scene_path;
    const char *output_path;
    const char *png_path;
    const char *stats_path;
    int aov_png;               /* --aov-png: false-colour PNGs of the single-channel AOV layers */
    uint64_t max_image_pixels; /* --max-image-pixels; 0 = the library's default */
    double exposure;
    int quiet;
    int has_spp, has_threshold;
    int integrator, driver; /* method indices (pn_method_get) */
    pn_render_settings settings;
    pn_options options; /* owned; settings.options points to it */
} render_options;
/* Parses the arguments of `render` into o (o->options must be a fresh handle). Returns -1 to
 * continue, or an exit code. */
int parse_render_args(int argc, char **argv, render_options *o);
/* The help of `render`: everything, or (method >= 0) the common options and that method's. */
void print_render_help(FILE *out, int integrator, int driver);
int command_methods(int argc, char **argv);
/* "shadow_rays, eye_rays, ..." for AOV bits. */
void format_aov_names(uint32_t bits, char *buf, size_t size);

/* report.c: the summary and the statistics JSON. */
void print_render_summary(const render_options *o, const pn_scene_info *info, pn_stats stats, const char *image_path);
/* Adds the statistics JSON to `set` (renamed into place by the caller's commit). */
int write_stats_json(const render_options *o, pn_output_set outputs, const char *image_path, pn_scene scene,
                     const pn_scene_info *info, pn_stats stats, int interrupted_render);
/* Prints a cJSON tree (a `struct cJSON *`) with two-space indentation; caller frees the text. */
char *json_print(const void *tree);

/* The commands. */
int command_render(int argc, char **argv);
int command_diff(int argc, char **argv);
int command_info(int argc, char **argv);
int command_ies2goniometric(int argc, char **argv);
/* illuminance.c: calculation grids and false colour (docs/lighting-design.md) */
int command_illuminance(int argc, char **argv);
int command_falsecolor(int argc, char **argv);
int command_merge(int argc, char **argv);

/* util.c: opens an input for reading only when it is a regular file (a FIFO or device is refused
 * without blocking); NULL with *why set otherwise. */
FILE *cli_open_regular(const char *path, const char *mode, const char **why);

extern const char diff_help[], info_help[], ies2goniometric_help[];

#endif
