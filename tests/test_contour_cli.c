/* test_contour_cli.c — the `penumbra render` options of the contour integrators: bad values are
 * usage errors (exit 2) with a message naming the option; a good run writes the gradient layer
 * and the Table 1 statistics. */
#include "harness.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static char dir[256];

/* Runs the CLI with `args` (a shell-quoted string), returns the exit code; stderr in *err. */
static int run(const char *args, char *err, size_t err_size) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "'%s' %s 2>'%s/err.txt' >/dev/null", PN_CLI_PATH, args, dir);
    int status = system(cmd);
    char path[512];
    snprintf(path, sizeof path, "%s/err.txt", dir);
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(err, 1, err_size - 1, f) : 0;
    err[n] = 0;
    if (f) fclose(f);
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

static const char *scene_text =
    "LookAt 0 -3 2.5  0 0 0  0 0 1\n"
    "Camera \"perspective\" \"float fov\" [ 50 ]\n"
    "Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n"
    "WorldBegin\n"
    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n"
    "Shape \"trianglemesh\" \"point3 P\" [ -5 -5 0  5 -5 0  5 5 0  -5 5 0 ] \"integer indices\" [ 0 1 2  0 2 3 ]\n"
    "AttributeBegin\n  Translate 0.2 0.1 0.6\n  Shape \"sphere\" \"float radius\" [ 0.25 ]\nAttributeEnd\n"
    "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [ 3 3 3 ]\n"
    "  Shape \"trianglemesh\" \"point3 P\" [ -0.5 -0.5 1.2  -0.5 0.5 1.2  0.5 0.5 1.2  0.5 -0.5 1.2 ]\n"
    "     \"integer indices\" [ 0 1 2  0 2 3 ]\nAttributeEnd\n";

static void test_bad_options(void) {
    const char *scene = pn_test_write_file(dir, "s.pbrt", scene_text);
    static const struct {
        const char *args, *expect;
    } cases[] = {
        {"--contour-grid 1", "--contour-grid"},   {"--contour-grid 66", "--contour-grid"},
        {"--contour-steps 0", "--contour-steps"}, {"--contour-steps 13", "--contour-steps"},
        {"--contour-span 0", "--contour-span"},   {"--contour-off shadows", "--contour-off"},
        {"--mc-threshold -1", "--mc-threshold"},  {"--mc-max-rays 2", "--mc-max-rays"},
        {"--aov gradients", "gradients"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char args[4096], err[4096];
        snprintf(args, sizeof args, "render '%s' --integrator contour %s -o '%s/o.exr'", scene, cases[i].args, dir);
        int code = run(args, err, sizeof err);
        CHECK_MSG(code == 2, "%s: exit %d", cases[i].args, code);
        CHECK_STR_CONTAINS(err, cases[i].expect);
    }
    /* Too large a sample array: a clear message from the library, exit 2 (invalid argument). */
    char args[4096], err[4096];
    snprintf(args, sizeof args, "render '%s' --integrator contour --contour-grid 65 --contour-steps 12 -o '%s/o.exr'",
             scene, dir);
    CHECK(run(args, err, sizeof err) != 0);
    CHECK_STR_CONTAINS(err, "sample array");
}

static void test_good_run(void) {
    const char *scene = pn_test_write_file(dir, "s2.pbrt", scene_text);
    char args[4096], err[4096];
    snprintf(args, sizeof args,
             "render '%s' --integrator contour --aov gradient,shadow_rays --stats '%s/s.json' -o '%s/g.exr' --quiet",
             scene, dir, dir);
    CHECK(run(args, err, sizeof err) == 0);
    char path[512];
    snprintf(path, sizeof path, "%s/s.json", dir);
    FILE *f = fopen(path, "r");
    char json[16384];
    size_t n = f ? fread(json, 1, sizeof json - 1, f) : 0;
    json[n] = 0;
    if (f) fclose(f);
    CHECK_STR_CONTAINS(json, "\"integrator\": \"contour\"");
    CHECK_STR_CONTAINS(json, "contour_shadow_rays_per_viewing_ray");
    CHECK_STR_CONTAINS(json, "\"gradient\"");
}

static void test_setup(void) {
    snprintf(dir, sizeof dir, "/tmp/pn_test_contour_cli_XXXXXX");
    CHECK(mkdtemp(dir) != NULL);
    pn_test_remove_at_end(dir);
}

PN_TESTS(TEST(test_setup), TEST(test_bad_options), TEST(test_good_run))
