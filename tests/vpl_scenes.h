/* vpl_scenes.h — small scenes, a scratch folder and a scene loader shared by the VPL
 * integrators' tests (test_vpl, test_lightcuts, test_illumcut). Include after harness.h. */
#ifndef PN_TEST_VPL_SCENES_H
#define PN_TEST_VPL_SCENES_H

#include "penumbra/penumbra.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The test's scratch folder: made by vpl_test_setup, removed with its files by
 * vpl_test_teardown. */
static char tmpdir[256];

static inline void vpl_test_setup(const char *name) {
    snprintf(tmpdir, sizeof tmpdir, "/tmp/pn_test_%s_XXXXXX", name);
    CHECK(mkdtemp(tmpdir) != NULL);
}

static inline void vpl_test_teardown(void) {
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    CHECK(system(cmd) == 0);
}

/* Writes `text` as tmpdir/name and loads it; NULL (and a failed check) if it does not load. */
static inline pn_scene vpl_test_load(pn_context ctx, const char *name, const char *text) {
    const char *path = pn_test_write_file(tmpdir, name, text);
    pn_scene scene = NULL;
    CHECK(path && pn_scene_load(ctx, path, &scene) == PN_OK);
    return scene;
}

/* The index of img's layer called `name`, or -1. */
static inline int vpl_test_layer(pn_image img, const char *name) {
    for (int l = 0; l < pn_image_layer_count(img); l++)
        if (strcmp(pn_image_layer_name(img, l), name) == 0) return l;
    return -1;
}

/* A closed room (4 x 4 x 3) with a box standing on the floor, a point light and a rectangle
 * light under the ceiling: diffuse surfaces (the box glossy when `glossy`), occlusion, and
 * indirect light from every wall. */
static inline const char *pn_test_room_scene(int glossy, int width, int height) {
    static char text[4096];
    snprintf(
        text, sizeof text,
        "LookAt 0 -1.9 1.6  0 1 1.0  0 0 1\n"
        "Camera \"perspective\" \"float fov\" [ 70 ]\n"
        "Film \"rgb\" \"integer xresolution\" [ %d ] \"integer yresolution\" [ %d ]\n"
        "WorldBegin\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.7 0.7 0.7 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 -2 0  2 -2 0  2 2 0  -2 2 0 ]  \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 -2 3  -2 2 3  2 2 3  2 -2 3 ]  \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 2 0  2 2 0  2 2 3  -2 2 3 ]  \"integer indices\" [ 0 2 1  0 3 2 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 -2 0  -2 -2 3  2 -2 3  2 -2 0 ]  \"integer indices\" [ 0 2 1  0 3 2 "
        "]\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.7 0.2 0.2 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ -2 -2 0  -2 2 0  -2 2 3  -2 -2 3 ]  \"integer indices\" [ 0 2 1  0 3 2 "
        "]\n"
        "Material \"diffuse\" \"rgb reflectance\" [ 0.2 0.7 0.2 ]\n"
        "Shape \"trianglemesh\" \"point3 P\" [ 2 -2 0  2 -2 3  2 2 3  2 2 0 ]  \"integer indices\" [ 0 2 1  0 3 2 ]\n"
        "%s\n"
        "AttributeBegin\n"
        "  Translate 0.3 0.8 0.6\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ -0.5 -0.5 -0.6  0.5 -0.5 -0.6  0.5 0.5 -0.6  -0.5 0.5 -0.6\n"
        "     -0.5 -0.5 0.6  0.5 -0.5 0.6  0.5 0.5 0.6  -0.5 0.5 0.6 ]\n"
        "     \"integer indices\" [ 4 5 6  4 6 7  0 1 5  0 5 4  1 2 6  1 6 5  2 3 7  2 7 6  3 0 4  3 4 7 ]\n"
        "AttributeEnd\n"
        "LightSource \"point\" \"point3 from\" [ -1.2 0.5 2.2 ] \"rgb I\" [ 1.5 1.4 1.2 ]\n"
        "AttributeBegin\n"
        "  AreaLightSource \"diffuse\" \"rgb L\" [ 3 3 3 ]\n"
        "  Shape \"trianglemesh\" \"point3 P\" [ 0.5 -0.5 2.95  0.5 0.2 2.95  1.2 0.2 2.95  1.2 -0.5 2.95 ]\n"
        "     \"integer indices\" [ 0 1 2  0 2 3 ]\n"
        "AttributeEnd\n",
        width, height,
        glossy ? "Material \"coateddiffuse\" \"rgb reflectance\" [ 0.5 0.5 0.6 ] \"float roughness\" [ 0.1 ]"
               : "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.6 ]");
    return text;
}

#endif
