/* main.c — the `penumbra` command-line program: `render`, `methods`, `diff` and `info`, built on
 * the public header only. This file holds the command dispatch and the fixed help texts; the
 * commands live in render_cmd.c (render), options.c (render's options and `methods`, generated
 * from the library's method table), report.c (summary and statistics JSON) and inspect.c (diff,
 * info).
 *
 * Numbers are parsed strictly (the whole string must be a number in range), problems with the
 * command line exit with status 2 and a one-line message that names the option, and library
 * errors are mapped onto the exit codes documented in README.md:
 *
 *   0 success, 2 usage, 3 bad input, 4 system error, 70 internal error, 130 interrupted.
 *
 * No file is ever left half-written: the library writes images and the statistics JSON to
 * temporaries and renames them together once all are complete (pn_output_set_*).
 */
#include "cli/cli.h"

#include <string.h>

static const char main_help[] =
    "penumbra - many-light renderer for pbrt-v4 scenes\n"
    "\n"
    "usage:\n"
    "  penumbra render SCENE.pbrt [options]   render a scene to EXR (and PNG)\n"
    "  penumbra methods [NAME]                list the integrators and drivers and their options\n"
    "  penumbra diff REFERENCE IMAGE [options] compare two images (RMSE, relMSE, ...)\n"
    "  penumbra info SCENE.pbrt               describe a scene: geometry, lights, materials\n"
    "  penumbra ies2goniometric LAMP.ies -o LAMP.exr  a measured luminaire as pbrt-v4's goniometric image\n"
    "  penumbra illuminance SCENE.pbrt ...    illuminance (lux) on a work-plane grid or at points\n"
    "  penumbra falsecolor IN.exr -o OUT.png  false colour of a layer with a legend in lux or cd/m2\n"
    "  penumbra merge PARTS... -o FULL.exr    assemble crop renders (--crop, --piece K/M) into one image\n"
    "  penumbra --help | --version\n"
    "\n"
    "Run 'penumbra COMMAND --help' for the options of a command.\n"
    "\n"
    "exit status: 0 success, 2 usage error, 3 bad input (scene or image file), 4 system error\n"
    "(I/O, memory), 70 internal error, 130 interrupted.\n";

const char diff_help[] =
    "usage: penumbra diff REFERENCE IMAGE [options]\n"
    "\n"
    "Compares IMAGE against REFERENCE (EXR, PFM, HDR, PNG, TGA or JPG; both the same size) and\n"
    "prints RMSE, relMSE (mean of (a-b)^2 / (b^2 + epsilon), epsilon 0.01), the relative L1 and L2\n"
    "norms of the difference, the mean absolute error and both mean luminances.\n"
    "\n"
    "options:\n"
    "  --error-image FILE     write |IMAGE - REFERENCE| x 16 as an image (.exr, .pfm or .png)\n"
    "  --json                 print the metrics as JSON instead of text\n" MAX_IMAGE_PIXELS_HELP;

const char info_help[] =
    "usage: penumbra info SCENE.pbrt\n"
    "\n"
    "Loads SCENE.pbrt and prints what penumbra made of it: triangles, meshes, instances, spheres,\n"
    "lights by kind, measured luminaires (IES, EULUMDAT: the lumens each emits, integrated from its\n"
    "distribution, next to the lumens its file states), materials and how each pbrt material was\n"
    "mapped, textures, bounds, film resolution, load times and the warnings raised while loading.\n"
    "\n"
    "options:\n" MAX_IMAGE_PIXELS_HELP;

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
    if (strcmp(command, "render") == 0) return command_render(argc - 1, argv + 1);
    if (strcmp(command, "methods") == 0) return command_methods(argc - 1, argv + 1);
    if (strcmp(command, "diff") == 0) return command_diff(argc - 1, argv + 1);
    if (strcmp(command, "info") == 0) return command_info(argc - 1, argv + 1);
    if (strcmp(command, "ies2goniometric") == 0) return command_ies2goniometric(argc - 1, argv + 1);
    if (strcmp(command, "illuminance") == 0) return command_illuminance(argc - 1, argv + 1);
    if (strcmp(command, "falsecolor") == 0) return command_falsecolor(argc - 1, argv + 1);
    if (strcmp(command, "merge") == 0) return command_merge(argc - 1, argv + 1);
    if (strcmp(command, "--help") == 0 || strcmp(command, "-h") == 0 || strcmp(command, "help") == 0) {
        if (argc >= 3 && strcmp(command, "help") == 0) {
            if (strcmp(argv[2], "render") == 0)
                print_render_help(stdout, -1, -1);
            else if (strcmp(argv[2], "methods") == 0)
                return command_methods(2, (char *[]){"methods", "--help", NULL});
            else if (strcmp(argv[2], "diff") == 0)
                fputs(diff_help, stdout);
            else if (strcmp(argv[2], "info") == 0)
                fputs(info_help, stdout);
            else if (strcmp(argv[2], "ies2goniometric") == 0)
                fputs(ies2goniometric_help, stdout);
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
    if (command[0] == '-') return usage_error(NULL, "unknown option '%s'", command);
    return usage_error(NULL, "unknown command '%s'", command);
}
