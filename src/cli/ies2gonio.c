/* ies2gonio.c — `penumbra ies2goniometric`: a measured luminaire (IES LM-63 or EULUMDAT) as
 * pbrt-v4's goniometric image, so that the same luminaire renders in pbrt-v4 (which reads no
 * photometric files) as LightSource "goniometric" "string filename" "lamp.exr". */
#include "cli/cli.h"

#include <stdlib.h>
#include <string.h>

const char ies2goniometric_help[] =
    "usage: penumbra ies2goniometric LAMP.ies|LAMP.ldt -o LAMP.exr [--resolution N]\n"
    "\n"
    "Writes pbrt-v4's goniometric image of a measured luminaire: a square N x N EXR (default\n"
    "512) in pbrt-v4's equal-area octahedral mapping of its light frame (y and z swapped), each\n"
    "pixel the mean candela over its solid angle. In pbrt-v4 (and penumbra), LightSource\n"
    "\"goniometric\" \"string filename\" \"LAMP.exr\" under a transform is the luminaire that\n"
    "LightSource \"goniometric\" \"string filename\" \"LAMP.ies\" is in penumbra under the same\n"
    "transform (docs/luminaires.md).\n"
    "\n"
    "options:\n"
    "  -o FILE                the image to write (.exr)\n"
    "  --resolution N         pixels per side, 1 to 16384 (default 512)\n";

int command_ies2goniometric(int argc, char **argv) {
    const char *cmd = "ies2goniometric";
    const char *input = NULL, *output = NULL, *positional = NULL, *value;
    long resolution = 512;
    int kind;
    arg_scanner s = {cmd, argc, argv, 0, {0}, NULL, 0};
    while ((kind = scanner_next(&s, &positional)) != 0) {
        if (kind == 2) {
            if (input) return usage_error(cmd, "unexpected argument '%s'", positional);
            input = positional;
        } else if (strcmp(s.name, "-h") == 0 || strcmp(s.name, "--help") == 0) {
            fputs(ies2goniometric_help, stdout);
            return EXIT_OK;
        } else if (strcmp(s.name, "-o") == 0 || strcmp(s.name, "--output") == 0) {
            if ((value = scanner_value(&s)) == NULL) return EXIT_USAGE;
            size_t n = strlen(value);
            if (n < 5 || strcmp(value + n - 4, ".exr") != 0)
                return bad_value(cmd, s.name, value, "a file name ending in .exr");
            output = value;
        } else if (strcmp(s.name, "--resolution") == 0) {
            if ((value = scanner_value(&s)) == NULL) return EXIT_USAGE;
            char *end = NULL;
            resolution = strtol(value, &end, 10);
            if (!end || *end || resolution < 1 || resolution > 16384)
                return bad_value(cmd, s.name, value, "an integer from 1 to 16384");
        } else {
            return usage_error(cmd, "unknown option '%s'", s.argv[s.index]);
        }
    }
    if (!input) return usage_error(cmd, "needs a photometric file (.ies or .ldt)");
    if (!output) return usage_error(cmd, "needs -o FILE.exr");
    int code;
    if ((code = check_input_file(input)) != EXIT_OK) return code;
    if ((code = check_output_folder(output)) != EXIT_OK) return code;
    pn_context ctx = pn_context_new();
    if (!ctx) {
        fprintf(stderr, "penumbra: out of memory\n");
        return EXIT_SYSTEM;
    }
    pn_image img = NULL;
    pn_status st = pn_photometry_goniometric_image(ctx, input, (int)resolution, &img);
    if (st == PN_OK) st = pn_image_write(ctx, img, output, 0.0f);
    code = st == PN_OK ? EXIT_OK : report_failure(ctx, st);
    if (st == PN_OK) printf("wrote %s (%ld x %ld)\n", output, resolution, resolution);
    pn_image_free(img);
    pn_context_free(ctx);
    return code;
}
