/* test_parser.c — the pbrt-v4 scene parser: transforms, graphics state, Include, instancing,
 * shapes, area lights, named materials, the bad-input error table (exact line:column) and, when
 * ../shared is present, every real scene. */
#define _XOPEN_SOURCE 700 /* nftw, mkdtemp */
#include "harness.h"

#include "core/context.h"
#include "scene/build.h"
#include "scene/scene.h"

#include <dirent.h>
#include <ftw.h>
#include <errno.h>
#include <stdarg.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define PN_SCENE_FILES_PREFIX "pn_test_parser"
#include "scene_files.h"

/* ---- helpers ----------------------------------------------------------------------------- */

static struct pn_scene_s *parse_ok(const char *rel, const char *text) {
    write_file(rel, text);
    pn_err err;
    pn_err_init(&err);
    struct pn_scene_s *s = NULL;
    pn_status st = pn_scene_parse(test_context(), tpath(rel), &s, &err);
    CHECK_MSG(st == PN_OK, "%s: status %d: %s", rel, (int)st, err.message);
    return st == PN_OK ? s : NULL;
}

static bool has_warning(const struct pn_scene_s *s, const char *needle) {
    for (int i = 0; i < s->warnings.count; i++)
        if (strstr(s->warnings.items[i], needle)) return true;
    return false;
}

static void check_point(vec3 got, double x, double y, double z, double tol) {
    CHECK_NEAR(got.x, x, tol);
    CHECK_NEAR(got.y, y, tol);
    CHECK_NEAR(got.z, z, tol);
}

static vec3 mesh_vertex(const pn_mesh *m, uint32_t i) {
    return v3(m->positions[3 * i], m->positions[3 * i + 1], m->positions[3 * i + 2]);
}

#define TRI "Shape \"trianglemesh\" \"point3 P\" [1 0 0  0 1 0  0 0 1]\n"

/* ---- transforms and camera --------------------------------------------------------------- */

static void test_look_at_camera(void) {
    struct pn_scene_s *s =
        parse_ok("camera.pbrt", "LookAt 0 0 5   0 0 0   0 1 0\n"
                                "Camera \"perspective\" \"float fov\" [ 45 ]\n"
                                "Film \"rgb\" \"integer xresolution\" 200 \"integer yresolution\" [100]\n"
                                "  \"string filename\" \"out.exr\"\n"
                                "Sampler \"zsobol\" \"integer pixelsamples\" 64\n"
                                "Integrator \"path\" \"integer maxdepth\" [ 1 ]\n"
                                "PixelFilter \"box\"\n"
                                "WorldBegin\n" TRI);
    if (!s) return;
    const pn_camera_def *c = &s->camera;
    /* pbrt's camera looks down +z; +y is up and +x = up x view (left-handed). */
    check_point(mat4_apply_point(&c->camera_from_world, v3(0, 0, 0)), 0, 0, 5, 1e-5);
    check_point(mat4_apply_point(&c->camera_from_world, v3(0, 1, 0)), 0, 1, 5, 1e-5);
    check_point(mat4_apply_point(&c->camera_from_world, v3(1, 0, 0)), -1, 0, 5, 1e-5);
    check_point(mat4_apply_point(&c->world_from_camera, v3(0, 0, 0)), 0, 0, 5, 1e-5);
    CHECK_NEAR(c->fov_deg, 45.0, 1e-6);
    CHECK(c->width == 200 && c->height == 100);
    CHECK_NEAR(c->screen_window[0], -2.0, 1e-6);
    CHECK_NEAR(c->screen_window[1], 2.0, 1e-6);
    CHECK_NEAR(c->screen_window[2], -1.0, 1e-6);
    CHECK_NEAR(c->screen_window[3], 1.0, 1e-6);
    CHECK(c->pixel_samples == 64);
    CHECK(c->max_depth == 1);
    CHECK(c->integrator_name && strcmp(c->integrator_name, "path") == 0);
    CHECK(c->film_filename && strcmp(c->film_filename, "out.exr") == 0);
    CHECK(c->filter == PN_FILTER_BOX);
    CHECK_NEAR(c->filter_radius[0], 0.5, 1e-6);
    CHECK(s->parse_seconds >= 0.0);
    pn_scene_parse_free(s);
}

static void test_transform_composition(void) {
    struct pn_scene_s *s =
        parse_ok("xform.pbrt", "Camera \"perspective\"\nWorldBegin\n"
                               "AttributeBegin\n"
                               "  Translate 1 2 3\n  Rotate 90 0 0 1\n  Scale 2 2 2\n" TRI "AttributeEnd\n"
                               "AttributeBegin\n"
                               "  Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1]\n"
                               "  ConcatTransform [2 0 0 0  0 2 0 0  0 0 2 0  0 0 0 1]\n" TRI
                               "  Identity\n  Translate 0 0 -1\n" TRI "AttributeEnd\n"
                               "TransformBegin\n  Translate 100 0 0\nTransformEnd\n" TRI);
    if (!s) return;
    CHECK(s->mesh_count == 4);
    if (s->mesh_count == 4) {
        /* p -> Translate(Rotate(Scale(p))) */
        check_point(mesh_vertex(&s->meshes[0], 0), 1, 4, 3, 1e-5);
        check_point(mesh_vertex(&s->meshes[0], 1), -1, 2, 3, 1e-5);
        check_point(mesh_vertex(&s->meshes[0], 2), 1, 2, 5, 1e-5);
        check_point(mesh_vertex(&s->meshes[1], 0), 7, 6, 7, 1e-5);
        check_point(mesh_vertex(&s->meshes[1], 2), 5, 6, 9, 1e-5);
        check_point(mesh_vertex(&s->meshes[2], 0), 1, 0, -1, 1e-5);
        check_point(mesh_vertex(&s->meshes[3], 0), 1, 0, 0, 1e-6);
        CHECK(s->meshes[0].triangle_count == 1);
        CHECK(s->meshes[0].indices[0] == 0 && s->meshes[0].indices[1] == 1 && s->meshes[0].indices[2] == 2);
    }
    check_point(s->bounds_min, -1, 0, -1, 1e-5);
    check_point(s->bounds_max, 7, 8, 9, 1e-5);
    pn_scene_parse_free(s);
}

static void test_coordinate_systems(void) {
    struct pn_scene_s *s =
        parse_ok("coordsys.pbrt", "Translate 0 0 10\n"
                                  "Camera \"perspective\"\n"
                                  "WorldBegin\n"
                                  "Translate 3 0 0\nCoordinateSystem \"here\"\nIdentity\n"
                                  "AttributeBegin\n CoordSysTransform \"camera\"\n" TRI "AttributeEnd\n"
                                  "AttributeBegin\n CoordSysTransform \"here\"\n" TRI "AttributeEnd\n");
    if (!s) return;
    CHECK(s->mesh_count == 2);
    if (s->mesh_count == 2) {
        /* camera_from_world = Translate(0,0,10), so "camera" space is world_from_camera */
        check_point(mesh_vertex(&s->meshes[0], 0), 1, 0, -10, 1e-5);
        check_point(mesh_vertex(&s->meshes[1], 0), 4, 0, 0, 1e-5);
    }
    pn_scene_parse_free(s);
}

/* ---- graphics state ---------------------------------------------------------------------- */

static void test_attribute_scoping(void) {
    struct pn_scene_s *s = parse_ok("scope.pbrt", "WorldBegin\n"
                                                  "Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n"
                                                  "AttributeBegin\n"
                                                  "  Translate 10 0 0\n"
                                                  "  Material \"diffuse\" \"rgb reflectance\" [0.9 0.9 0.9]\n"
                                                  "  ReverseOrientation\n" TRI "AttributeEnd\n" TRI);
    if (!s) return;
    CHECK(s->mesh_count == 2);
    if (s->mesh_count == 2) {
        check_point(mesh_vertex(&s->meshes[0], 0), 11, 0, 0, 1e-6);
        check_point(mesh_vertex(&s->meshes[1], 0), 1, 0, 0, 1e-6);
        CHECK(s->meshes[0].material != s->meshes[1].material);
        CHECK(s->meshes[0].flip_normals);
        CHECK(!s->meshes[1].flip_normals);
        CHECK(s->meshes[0].emission == -1 && s->meshes[1].emission == -1);
        CHECK(s->meshes[0].object == -1);
        CHECK_STR_CONTAINS(s->meshes[0].source, "scope.pbrt:7");
    }
    pn_scene_parse_free(s);
}

static void test_default_material(void) {
    struct pn_scene_s *s = parse_ok("defmat.pbrt", "WorldBegin\n" TRI TRI);
    if (!s) return;
    CHECK(s->material_count == 1);
    CHECK(s->mesh_count == 2 && s->meshes[0].material == 0 && s->meshes[1].material == 0);
    pn_scene_parse_free(s);
}

static void test_reverse_orientation_and_handedness(void) {
    struct pn_scene_s *s =
        parse_ok("flip.pbrt", "WorldBegin\n"
                              "AttributeBegin\n Scale -1 1 1\n" TRI "AttributeEnd\n"
                              "AttributeBegin\n Scale -1 1 1\n ReverseOrientation\n" TRI "AttributeEnd\n"
                              "AttributeBegin\n ReverseOrientation\n Shape \"sphere\"\nAttributeEnd\n"
                              "Shape \"sphere\" \"float radius\" 2\n");
    if (!s) return;
    CHECK(s->mesh_count == 2 && s->sphere_count == 2);
    if (s->mesh_count == 2) {
        CHECK(s->meshes[0].flip_normals);
        CHECK(!s->meshes[1].flip_normals);
    }
    if (s->sphere_count == 2) {
        CHECK(s->spheres[0].flip_normals);
        CHECK(!s->spheres[1].flip_normals);
        CHECK_NEAR(s->spheres[1].radius, 2.0, 1e-6);
    }
    pn_scene_parse_free(s);
}

static void test_attribute_defaults(void) {
    struct pn_scene_s *s = parse_ok("attrdef.pbrt", "WorldBegin\n"
                                                    "AttributeBegin\n"
                                                    "  Attribute \"shape\" \"float radius\" [ 3 ]\n"
                                                    "  Shape \"sphere\"\n"
                                                    "  Shape \"sphere\" \"float radius\" 0.5\n"
                                                    "AttributeEnd\n"
                                                    "Shape \"sphere\"\n");
    if (!s) return;
    CHECK(s->sphere_count == 3);
    if (s->sphere_count == 3) {
        CHECK_NEAR(s->spheres[0].radius, 3.0, 1e-6);
        CHECK_NEAR(s->spheres[1].radius, 0.5, 1e-6);
        CHECK_NEAR(s->spheres[2].radius, 1.0, 1e-6);
    }
    CHECK(s->warnings.count == 0);
    pn_scene_parse_free(s);
}

/* ---- Include ----------------------------------------------------------------------------- */

static void test_include_relative(void) {
    write_file("inc/more.pbrt", "Translate 0 0 1\n" TRI);
    /* pbrt-v4 resolves an included file's paths against the main file's folder */
    write_file("inc/part.pbrt", "# included\nAttributeBegin\nInclude \"inc/more.pbrt\"\nAttributeEnd\n" TRI);
    struct pn_scene_s *s =
        parse_ok("inc_main.pbrt", "WorldBegin\nInclude \"inc/part.pbrt\"\nImport \"inc/more.pbrt\"\n" TRI);
    if (!s) return;
    CHECK(s->mesh_count == 4);
    if (s->mesh_count == 4) {
        check_point(mesh_vertex(&s->meshes[0], 0), 1, 0, 1, 1e-6);
        check_point(mesh_vertex(&s->meshes[1], 0), 1, 0, 0, 1e-6); /* AttributeEnd restored the CTM */
        check_point(mesh_vertex(&s->meshes[2], 0), 1, 0, 1, 1e-6);
        check_point(mesh_vertex(&s->meshes[3], 0), 1, 0, 1, 1e-6); /* the Include changed the CTM */
        CHECK_STR_CONTAINS(s->meshes[0].source, "inc/more.pbrt:2");
        CHECK_STR_CONTAINS(s->meshes[1].source, "inc/part.pbrt:5");
    }
    pn_scene_parse_free(s);
}

/* ---- instancing -------------------------------------------------------------------------- */

static void test_object_instances(void) {
    struct pn_scene_s *s =
        parse_ok("inst.pbrt", "WorldBegin\n"
                              "ObjectInstance \"later\"\n" /* pbrt-v4 resolves names at the end */
                              "ObjectBegin \"a\"\n"
                              "  Translate 1 0 0\n" TRI "  Shape \"sphere\" \"float radius\" 0.5\n"
                              "ObjectEnd\n"
                              "AttributeBegin\n Translate 0 10 0\n ObjectInstance \"a\"\nAttributeEnd\n"
                              "ObjectInstance \"a\"\n"
                              "ObjectBegin \"later\"\n" TRI "ObjectEnd\n" TRI);
    if (!s) return;
    CHECK(s->object_count == 2);
    CHECK(s->instance_count == 3);
    CHECK(s->mesh_count == 3);
    if (s->object_count == 2 && s->instance_count == 3 && s->mesh_count == 3) {
        const pn_object *a = &s->objects[0];
        CHECK(strcmp(a->name, "a") == 0);
        CHECK(a->first_mesh == 0 && a->mesh_count == 1 && a->first_sphere == 0 && a->sphere_count == 1);
        CHECK(s->meshes[0].object == 0 && s->spheres[0].object == 0);
        CHECK(s->meshes[1].object == 1 && s->meshes[2].object == -1);
        /* the object's own transform is baked into its meshes */
        check_point(mesh_vertex(&s->meshes[0], 0), 2, 0, 0, 1e-6);
        check_point(s->spheres[0].center, 1, 0, 0, 1e-6);
        CHECK(s->instances[0].object == 1);
        CHECK(s->instances[1].object == 0 && s->instances[2].object == 0);
        check_point(mat4_apply_point(&s->instances[1].world_from_object, v3(0, 0, 0)), 0, 10, 0, 1e-6);
        check_point(mat4_apply_point(&s->instances[2].world_from_object, v3(0, 0, 0)), 0, 0, 0, 1e-6);
        /* bounds include the instances: instance 1 of "a" reaches y = 11 */
        CHECK_NEAR(s->bounds_max.y, 11.0, 1e-5);
    }
    pn_scene_parse_free(s);
}

/* ---- shapes ------------------------------------------------------------------------------ */

static void test_trianglemesh_contents(void) {
    struct pn_scene_s *s = parse_ok("mesh.pbrt", "WorldBegin\n"
                                                 "Translate 0 0 2\nScale 2 1 1\n"
                                                 "Shape \"trianglemesh\" \"integer indices\" [0 1 2  2 3 0]\n"
                                                 "  \"point P\" [0 0 0  1 0 0  1 1 0  0 1 0]\n"
                                                 "  \"normal N\" [1 0 1  1 0 1  1 0 1  1 0 1]\n"
                                                 "  \"point2 uv\" [0 0 1 0 1 1 0 1]\n"
                                                 "  \"vector3 S\" [1 0 0 1 0 0 1 0 0 1 0 0]\n"
                                                 "  \"float alpha\" 0.5\n");
    if (!s) return;
    CHECK(s->mesh_count == 1);
    if (s->mesh_count == 1) {
        const pn_mesh *m = &s->meshes[0];
        CHECK(m->vertex_count == 4 && m->triangle_count == 2);
        CHECK(m->indices[3] == 2 && m->indices[4] == 3 && m->indices[5] == 0);
        check_point(mesh_vertex(m, 2), 2, 1, 2, 1e-6);
        CHECK(m->normals != NULL && m->uvs != NULL);
        if (m->normals) {
            /* inverse transpose of Scale(2,1,1) maps (1,0,1) to (0.5,0,1), then normalised */
            double l = sqrt(1.25);
            check_point(v3(m->normals[0], m->normals[1], m->normals[2]), 0.5 / l, 0, 1 / l, 1e-5);
        }
        if (m->uvs) CHECK(m->uvs[4] == 1.0f && m->uvs[5] == 1.0f);
        CHECK(m->alpha.texture < 0);
        CHECK_NEAR(m->alpha.value.x, 0.5, 1e-6);
        CHECK(!m->flip_normals);
    }
    CHECK(s->warnings.count == 0);
    pn_scene_parse_free(s);
}

static void test_disk_and_sphere(void) {
    struct pn_scene_s *s =
        parse_ok("quadrics.pbrt", "WorldBegin\n"
                                  "AttributeBegin\n"
                                  "  Translate 1 2 3\n  Rotate 90 1 0 0\n"
                                  "  Shape \"disk\" \"float height\" 1 \"float radius\" 3 \"float innerradius\" 1\n"
                                  "AttributeEnd\n"
                                  "AttributeBegin\n"
                                  "  Translate 0 5 0\n  Scale 2 2 2\n"
                                  "  Shape \"sphere\" \"float radius\" 1.5\n"
                                  "AttributeEnd\n"
                                  "AttributeBegin\n  Scale 1 2 4\n  Shape \"sphere\"\nAttributeEnd\n");
    if (!s) return;
    CHECK(s->disk_count == 1 && s->sphere_count == 2 && s->mesh_count == 1);
    if (s->disk_count == 1 && s->mesh_count == 1) {
        const pn_disk *d = &s->disks[0];
        /* Rotate 90 about x maps z to -y: the centre (0,0,1) goes to (0,-1,0) */
        check_point(d->center, 1, 1, 3, 1e-5);
        check_point(d->normal, 0, -1, 0, 1e-5);
        CHECK_NEAR(d->radius, 3.0, 1e-5);
        CHECK_NEAR(d->inner_radius, 1.0, 1e-5);
        CHECK(d->mesh == 0 && s->meshes[0].disk == 0);
        CHECK(s->meshes[0].triangle_count == 128);
        /* the tessellation faces the same way as the disk */
        const pn_mesh *m = &s->meshes[0];
        vec3 p0 = mesh_vertex(m, m->indices[0]), p1 = mesh_vertex(m, m->indices[1]), p2 = mesh_vertex(m, m->indices[2]);
        vec3 n = v3_normalize(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0)));
        if (m->flip_normals) n = v3_neg(n);
        CHECK(v3_dot(n, d->normal) > 0.99f);
    }
    if (s->sphere_count == 2) {
        check_point(s->spheres[0].center, 0, 5, 0, 1e-6);
        CHECK_NEAR(s->spheres[0].radius, 3.0, 1e-5);
        CHECK_NEAR(s->spheres[1].radius, 2.0, 1e-5); /* cube root of 8 */
        CHECK(s->spheres[0].emission == -1);
    }
    CHECK(has_warning(s, "non-uniform"));
    pn_scene_parse_free(s);
}

/* Under a mirroring transform pbrt flips quadric normals (ReverseOrientation XOR handedness);
 * the disk record and its tessellation must agree. */
static void test_mirrored_disk(void) {
    struct pn_scene_s *s = parse_ok(
        "mirror_disk.pbrt", "WorldBegin\n"
                            "AttributeBegin\n Scale 1 1 -1\n Shape \"disk\"\nAttributeEnd\n"
                            "AttributeBegin\n Scale 1 1 -1\n ReverseOrientation\n Shape \"disk\"\nAttributeEnd\n");
    if (!s) return;
    CHECK(s->disk_count == 2);
    for (int i = 0; i < s->disk_count; i++) {
        const pn_disk *d = &s->disks[i];
        const pn_mesh *m = &s->meshes[d->mesh];
        check_point(d->normal, 0, 0, i == 0 ? 1 : -1, 1e-6);
        for (uint32_t t = 0; t < m->triangle_count; t++) {
            vec3 p0 = mesh_vertex(m, m->indices[3 * t]), p1 = mesh_vertex(m, m->indices[3 * t + 1]),
                 p2 = mesh_vertex(m, m->indices[3 * t + 2]);
            vec3 n = v3_normalize(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0)));
            if (m->flip_normals) n = v3_neg(n);
            CHECK(v3_dot(n, d->normal) > 0.99f);
        }
    }
    pn_scene_parse_free(s);
}

static void test_other_shapes(void) {
    struct pn_scene_s *s =
        parse_ok("shapes.pbrt", "WorldBegin\n"
                                "Shape \"bilinearmesh\" \"point3 P\" [0 0 0  1 0 0  0 1 0  1 1 0]\n"
                                "Shape \"loopsubdiv\" \"integer levels\" 0 \"integer indices\" [0 1 2]\n"
                                "  \"point3 P\" [0 0 0 1 0 0 0 1 0]\n"
                                "Shape \"cylinder\" \"float radius\" 0.5\n"
                                "Shape \"curve\" \"point3 P\" [0 0 0 1 1 1 2 2 2 3 3 3]\n"
                                "Shape \"teapot\"\n");
    if (!s) return;
    CHECK(s->mesh_count == 3);
    if (s->mesh_count == 3) {
        const pn_mesh *b = &s->meshes[0];
        CHECK(b->triangle_count == 2);
        /* both triangles of the patch face +z like pbrt's bilinear patch */
        for (uint32_t t = 0; t < b->triangle_count; t++) {
            vec3 p0 = mesh_vertex(b, b->indices[3 * t]), p1 = mesh_vertex(b, b->indices[3 * t + 1]),
                 p2 = mesh_vertex(b, b->indices[3 * t + 2]);
            CHECK(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0)).z > 0.0f);
        }
        CHECK(s->meshes[1].triangle_count == 1);
        CHECK(s->meshes[2].triangle_count == 128);
    }
    CHECK(has_warning(s, "curve"));
    CHECK(has_warning(s, "unknown shape type \"teapot\""));
    pn_scene_parse_free(s);
}

static void test_loop_subdivision(void) {
    /* a closed tetrahedron, one level: 4 -> 16 triangles, 4 + 6 vertices */
    struct pn_scene_s *s =
        parse_ok("loop.pbrt", "WorldBegin\n"
                              "Shape \"loopsubdiv\" \"integer levels\" 1\n"
                              "  \"point3 P\" [0 0 0  1 0 0  0 1 0  0 0 1]\n"
                              "  \"integer indices\" [0 2 1  0 1 3  0 3 2  1 2 3]\n"
                              "Shape \"loopsubdiv\" \"integer levels\" 2 \"point3 P\" [0 0 0 1 0 0 0 1 0]\n");
    if (!s) return;
    CHECK(s->mesh_count == 2);
    if (s->mesh_count == 2) {
        const pn_mesh *m = &s->meshes[0];
        CHECK(m->vertex_count == 10 && m->triangle_count == 16);
        /* even vertex 0 (valence 3, beta 3/16): 7/16 v0 + 3/16 (v1 + v2 + v3) */
        check_point(mesh_vertex(m, 0), 0.1875, 0.1875, 0.1875, 1e-6);
        /* an odd vertex on edge (0,1): 3/8 (v0 + v1) + 1/8 (v2 + v3) */
        bool found = false;
        for (uint32_t v = 4; v < m->vertex_count; v++) {
            vec3 p = mesh_vertex(m, v);
            if (fabsf(p.x - 0.375f) < 1e-6f && fabsf(p.y - 0.125f) < 1e-6f && fabsf(p.z - 0.125f) < 1e-6f) found = true;
        }
        CHECK(found);
        /* an open single triangle: boundary rules keep it in its plane; 2 levels -> 16 triangles */
        const pn_mesh *b = &s->meshes[1];
        CHECK(b->triangle_count == 16 && b->vertex_count == 15);
        for (uint32_t v = 0; v < b->vertex_count; v++) CHECK(b->positions[3 * v + 2] == 0.0f);
        /* boundary rule twice: (1/8, 1/8) after one level, then 3/4 of it + 1/8 of (1/2, 0) and (0, 1/2) */
        check_point(mesh_vertex(b, 0), 0.15625, 0.15625, 0, 1e-6);
    }
    pn_scene_parse_free(s);
}

/* ---- lights and materials ---------------------------------------------------------------- */

static void test_area_light(void) {
    struct pn_scene_s *s = parse_ok(
        "area.pbrt", "WorldBegin\n"
                     "AttributeBegin\n"
                     "  AreaLightSource \"diffuse\" \"rgb L\" [1 2 3] \"float scale\" 2\n" TRI "  Shape \"sphere\"\n"
                     "  ObjectBegin \"o\"\n" TRI "  ObjectEnd\n"
                     "AttributeEnd\n" TRI "LightSource \"point\" \"point3 from\" [0 1 0] \"rgb I\" [1 1 1]\n");
    if (!s) return;
    CHECK(s->mesh_count == 3 && s->sphere_count == 1);
    CHECK(s->emission_count == 2);
    if (s->mesh_count == 3 && s->sphere_count == 1 && s->emission_count == 2) {
        CHECK(s->meshes[0].emission == 0);
        CHECK(s->spheres[0].emission == 1);
        CHECK(s->meshes[1].emission == -1); /* inside an object definition: ignored */
        CHECK(s->meshes[2].emission == -1);
        CHECK_NEAR(s->emissions[0].radiance.x, 2.0, 1e-3);
        CHECK_NEAR(s->emissions[0].radiance.y, 4.0, 1e-3);
        CHECK_NEAR(s->emissions[0].radiance.z, 6.0, 1e-3);
    }
    CHECK(has_warning(s, "ObjectBegin"));
    CHECK(s->light_def_count == 1);
    pn_scene_parse_free(s);
}

static void test_named_materials(void) {
    struct pn_scene_s *s = parse_ok(
        "named.pbrt", "WorldBegin\n"
                      "MakeNamedMaterial \"red\" \"string type\" \"diffuse\" \"rgb reflectance\" [1 0 0]\n"
                      "MakeNamedMaterial \"with \\\"quotes\\\"\" \"string type\" [\"diffuse\"]\n"
                      "NamedMaterial \"red\"\n" TRI "NamedMaterial \"with \\\"quotes\\\"\"\n" TRI
                      "NamedMaterial \"later\"\n" TRI "MakeNamedMaterial \"later\" \"string type\" \"diffuse\"\n");
    if (!s) return;
    CHECK(s->mesh_count == 3);
    int red = pn_scene_find_material(s, "red"), q = pn_scene_find_material(s, "with \"quotes\""),
        later = pn_scene_find_material(s, "later");
    CHECK(red >= 0 && q >= 0 && later >= 0);
    if (s->mesh_count == 3) {
        CHECK(s->meshes[0].material == red);
        CHECK(s->meshes[1].material == q);
        CHECK(s->meshes[2].material == later);
    }
    pn_scene_parse_free(s);
}

static void test_unused_parameter_warning(void) {
    struct pn_scene_s *s = parse_ok("unused.pbrt", "Option \"bool disablepixeljitter\" true\n"
                                                   "WorldBegin\n"
                                                   "Shape \"sphere\" \"float radius\" 1\n"
                                                   "   \"float foo\" [ 2 ] \"bool bar\" \"true\"\n");
    if (!s) return;
    char expected[600];
    snprintf(expected, sizeof expected, "%s:4:4: unused parameter \"float foo\" for Shape \"sphere\"",
             tpath("unused.pbrt"));
    CHECK_MSG(has_warning(s, expected), "no warning \"%s\"", expected);
    snprintf(expected, sizeof expected, "%s:4:22: unused parameter \"bool bar\"", tpath("unused.pbrt"));
    CHECK_MSG(has_warning(s, expected), "no warning \"%s\"", expected);
    CHECK(has_warning(s, "Option"));
    pn_scene_parse_free(s);
}

static void test_motion_blur_warning(void) {
    struct pn_scene_s *s =
        parse_ok("motion.pbrt", "WorldBegin\n"
                                "ActiveTransform EndTime\nTranslate 5 0 0\nActiveTransform All\n" TRI);
    if (!s) return;
    CHECK(s->mesh_count == 1 && s->meshes[0].positions[0] == 1.0f);
    CHECK(has_warning(s, "motion blur"));
    pn_scene_parse_free(s);
}

/* ---- bad input: status and exact file:line:column ---------------------------------------- */

typedef struct bad_case {
    const char *text;
    pn_status status;
    int line, column;
    const char *fragment; /* expected in the message */
} bad_case;

#define TRI_P "\"point3 P\" [0 0 0 1 0 0 0 1 0]"

static const bad_case bad_cases[] = {
    {"Foo 1 2 3\n", PN_ERROR_BAD_INPUT, 1, 1, "unknown directive \"Foo\""},
    {"WorldBegin\nTranslate 1 2\nShape \"sphere\"\n", PN_ERROR_BAD_INPUT, 2, 1, "Translate needs 3 numbers, found 2"},
    {"WorldBegin\nTranslate 1 x 3\n", PN_ERROR_BAD_INPUT, 2, 1, "needs 3 numbers, found 1"},
    {"WorldBegin\nTranslate 1 2 3 4\n", PN_ERROR_BAD_INPUT, 2, 17, "unexpected number"},
    {"WorldBegin\nTranslate 1 nan 3\n", PN_ERROR_BAD_INPUT, 2, 13, "not a finite number"},
    {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 1e999 1 0]\n", PN_ERROR_BAD_INPUT, 2, 46,
     "not a finite number"},
    {"WorldBegin\nShape \"sphere\" \"float radius\" [1.5.2]\n", PN_ERROR_BAD_INPUT, 2, 32, "expected a number"},
    {"WorldBegin\nShape \"trianglemesh\"\n\"point3 P\"\n[ 0 0 0 1 0 0\n", PN_ERROR_BAD_INPUT, 4, 1,
     "ends inside the [ ] list"},
    {"WorldBegin\nShape \"sphere\n", PN_ERROR_BAD_INPUT, 2, 7, "unterminated string"},
    {"WorldBegin\nMaterial \"dif\\qfuse\"\n", PN_ERROR_BAD_INPUT, 2, 14, "escape"},
    {"WorldBegin\nAttributeEnd\n", PN_ERROR_BAD_INPUT, 2, 1, "without a matching AttributeBegin"},
    {"WorldBegin\nAttributeBegin\nTransformEnd\n", PN_ERROR_BAD_INPUT, 3, 1, "does not match"},
    {"WorldBegin\nAttributeBegin\n" TRI, PN_ERROR_BAD_INPUT, 2, 1, "never closed"},
    {"Camera \"perspective\"\n", PN_ERROR_BAD_INPUT, 2, 1, "before WorldBegin"},
    {"WorldBegin\n  Include \"missing.pbrt\"\n", PN_ERROR_BAD_INPUT, 2, 11, "missing.pbrt\": No such file"},
    {"WorldBegin\nShape \"trianglemesh\" " TRI_P "\n  \"integer indices\" [0 1 3]\n", PN_ERROR_BAD_INPUT, 3, 3,
     "out of range"},
    {"WorldBegin\nShape \"trianglemesh\" " TRI_P "\n  \"integer indices\" [0 1]\n", PN_ERROR_BAD_INPUT, 3, 3,
     "not a multiple of 3"},
    {"WorldBegin\nShape \"trianglemesh\" " TRI_P "\n  \"integer indices\" [0 1 1.5]\n", PN_ERROR_BAD_INPUT, 3, 26,
     "expects integers"},
    {"WorldBegin\nShape \"trianglemesh\"\n \"point3 P\" [0 0 0 1 0]\n", PN_ERROR_BAD_INPUT, 3, 2,
     "not a multiple of 3"},
    {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0 1 1 1]\n", PN_ERROR_BAD_INPUT, 2, 1,
     "needs an \"integer indices\""},
    {"WorldBegin\nShape \"trianglemesh\" " TRI_P "\n   \"normal N\" [0 0 1]\n", PN_ERROR_BAD_INPUT, 3, 4,
     "\"N\" has 1 normals"},
    {"WorldBegin\nShape \"trianglemesh\" " TRI_P "\n \"point2 uv\" [0 0 1 1]\n", PN_ERROR_BAD_INPUT, 3, 2,
     "\"uv\" has 2 coordinate pairs"},
    {"WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0]\n", PN_OK, 0, 0, NULL},
    {"WorldBegin\nScale 1 1 0\nShape \"trianglemesh\" " TRI_P " \"normal N\" [0 0 1 0 0 1 0 0 1]\n", PN_ERROR_BAD_INPUT,
     3, 1, "singular"},
    {"WorldBegin\n\nObjectInstance \"nope\"\n", PN_ERROR_BAD_INPUT, 3, 16, "undefined object \"nope\""},
    {"WorldBegin\nObjectBegin \"a\"\nObjectBegin \"b\"\n", PN_ERROR_BAD_INPUT, 3, 1, "cannot nest"},
    {"WorldBegin\nObjectEnd\n", PN_ERROR_BAD_INPUT, 2, 1, "ObjectEnd without"},
    {"WorldBegin\nNamedMaterial \"nothing\"\n" TRI, PN_ERROR_BAD_INPUT, 2, 15, "undefined named material"},
    {"Camera \"realistic\"\nWorldBegin\n", PN_ERROR_UNSUPPORTED, 1, 8, "not supported"},
    {"WorldBegin\nShape \"sphere\" \"flaot radius\" 1\n", PN_ERROR_BAD_INPUT, 2, 16, "unknown parameter type"},
    {"WorldBegin\nShape \"sphere\" \"float radius\" \"big\"\n", PN_ERROR_BAD_INPUT, 2, 31, "expects numbers"},
    {"WorldBegin\nShape \"sphere\" \"string radius\" \"big\"\n", PN_ERROR_BAD_INPUT, 2, 16, "but a float"},
    {"WorldBegin\nShape \"sphere\" \"float radius\" [1 2]\n", PN_ERROR_BAD_INPUT, 2, 16, "exactly 1 value"},
    {"WorldBegin\nShape \"sphere\" \"bool radius\" maybe\n", PN_ERROR_BAD_INPUT, 2, 30, "true or false"},
    {"WorldBegin\nShape \"sphere\" \"radius\" 1\n", PN_ERROR_BAD_INPUT, 2, 16, "type name"},
    {"Shape \"sphere\"\n", PN_ERROR_BAD_INPUT, 1, 1, "only allowed after WorldBegin"},
    {"WorldBegin\nFilm \"rgb\"\n", PN_ERROR_BAD_INPUT, 2, 1, "only allowed before WorldBegin"},
    {"WorldBegin\nWorldBegin\n", PN_ERROR_BAD_INPUT, 2, 1, "twice"},
    {"Transform [1 0 0 0\n", PN_ERROR_BAD_INPUT, 1, 1, "ends inside"},
    {"LookAt 0 0 0  0 0 0  0 1 0\n", PN_ERROR_BAD_INPUT, 1, 1, "degenerate"},
    {"Film \"rgb\" \"integer xresolution\" [0]\nWorldBegin\n", PN_ERROR_BAD_INPUT, 1, 12, "resolution"},
    {"WorldBegin\n\"float x\" 1\n", PN_ERROR_BAD_INPUT, 2, 1, "expected a directive"},
    {"WorldBegin\nShape \"plymesh\" \"string filename\" \"none.ply\"\n", PN_ERROR_BAD_INPUT, 2, 17, "none.ply"},
    {"WorldBegin\nActiveTransform Sometimes\n", PN_ERROR_BAD_INPUT, 2, 17, "StartTime"},
    {"WorldBegin\nRotate 30 0 0 0\n", PN_ERROR_BAD_INPUT, 2, 1, "zero rotation axis"},
    {"WorldBegin\nAttribute \"camera\" \"float fov\" 30\n", PN_ERROR_BAD_INPUT, 2, 11, "unknown Attribute target"},
    {"WorldBegin\nMakeNamedMaterial \"m\" \"rgb reflectance\" [1 1 1]\n", PN_ERROR_BAD_INPUT, 2, 1, "string type"},
};

static void test_bad_input_table(void) {
    for (size_t i = 0; i < sizeof bad_cases / sizeof bad_cases[0]; i++) {
        const bad_case *bc = &bad_cases[i];
        char rel[32];
        snprintf(rel, sizeof rel, "bad%02zu.pbrt", i);
        write_file(rel, bc->text);
        pn_err err;
        pn_err_init(&err);
        struct pn_scene_s *s = NULL;
        pn_status st = pn_scene_parse(test_context(), tpath(rel), &s, &err);
        CHECK_MSG(st == bc->status, "case %zu: status %d, expected %d (%s)", i, (int)st, (int)bc->status, err.message);
        if (st == PN_OK) {
            CHECK(s != NULL);
            pn_scene_parse_free(s);
            continue;
        }
        CHECK(s == NULL);
        char prefix[600];
        snprintf(prefix, sizeof prefix, "%s:%d:%d: ", tpath(rel), bc->line, bc->column);
        CHECK_MSG(strncmp(err.message, prefix, strlen(prefix)) == 0,
                  "case %zu: message \"%s\" does not start with \"%s\"", i, err.message, prefix);
        if (bc->fragment)
            CHECK_MSG(strstr(err.message, bc->fragment) != NULL, "case %zu: \"%s\" lacks \"%s\"", i, err.message,
                      bc->fragment);
    }
}

static void test_recursive_include(void) {
    write_file("rec/self.pbrt", "# includes itself\nInclude \"rec/self.pbrt\"\n");
    write_file("rec_main.pbrt", "WorldBegin\nInclude \"rec/self.pbrt\"\n");
    pn_err err;
    pn_err_init(&err);
    struct pn_scene_s *s = NULL;
    pn_status st = pn_scene_parse(test_context(), tpath("rec_main.pbrt"), &s, &err);
    CHECK(st == PN_ERROR_BAD_INPUT && s == NULL);
    char prefix[600];
    snprintf(prefix, sizeof prefix, "%s:2:9: ", tpath("rec/self.pbrt"));
    CHECK_MSG(strncmp(err.message, prefix, strlen(prefix)) == 0, "\"%s\" vs \"%s\"", err.message, prefix);
    CHECK_STR_CONTAINS(err.message, "deeper than 64");
}

static void test_missing_main_file(void) {
    pn_err err;
    pn_err_init(&err);
    struct pn_scene_s *s = NULL;
    pn_status st = pn_scene_parse(test_context(), tpath("does-not-exist.pbrt"), &s, &err);
    CHECK(st == PN_ERROR_BAD_INPUT && s == NULL);
    CHECK_STR_CONTAINS(err.message, "does-not-exist.pbrt");
}

/* Truncating a valid file at every byte must never crash or hang; most prefixes fail cleanly. */
static void test_truncated_prefixes(void) {
    const char *text = "LookAt 0 0 5 0 0 0 0 1 0\nCamera \"perspective\" \"float fov\" [45]\nWorldBegin\n"
                       "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
                       "Shape \"trianglemesh\" \"integer indices\" [0 1 2] \"point3 P\" [0 0 0 1 0 0 0 1 0]\n"
                       "AttributeEnd\nShape \"sphere\" \"float radius\" 2\n";
    size_t n = strlen(text);
    char *buf = malloc(n + 1);
    for (size_t k = 0; k <= n; k++) {
        memcpy(buf, text, k);
        buf[k] = '\0';
        write_file("trunc.pbrt", buf);
        pn_err err;
        pn_err_init(&err);
        struct pn_scene_s *s = NULL;
        pn_status st = pn_scene_parse(test_context(), tpath("trunc.pbrt"), &s, &err);
        CHECK(st == PN_OK || st == PN_ERROR_BAD_INPUT || st == PN_ERROR_UNSUPPORTED);
        CHECK((st == PN_OK) == (s != NULL));
        if (st != PN_OK)
            CHECK_MSG(strncmp(err.message, tpath("trunc.pbrt"), strlen(tpath("trunc.pbrt"))) == 0, "prefix %zu: %s", k,
                      err.message);
        pn_scene_parse_free(s);
    }
    free(buf);
}

/* Random byte edits of a valid scene: every result must be a clean success or error. */
static void test_mutations(void) {
    const char *text = "LookAt 0 0 5 0 0 0 0 1 0\nCamera \"perspective\" \"float fov\" [45]\n"
                       "Film \"rgb\" \"integer xresolution\" [64] \"integer yresolution\" [32]\nWorldBegin\n"
                       "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\nTranslate 1 2 3\n"
                       "Shape \"trianglemesh\" \"integer indices\" [0 1 2] \"point3 P\" [0 0 0 1 0 0 0 1 0]\n"
                       "AttributeEnd\nObjectBegin \"o\"\nShape \"disk\" \"float radius\" 2\nObjectEnd\n"
                       "ObjectInstance \"o\"\nMakeNamedMaterial \"m\" \"string type\" \"diffuse\"\n"
                       "NamedMaterial \"m\"\nShape \"sphere\" \"float radius\" 2\n";
    const char alphabet[] = "[]\"#\\ \n0123456789.-eE\0abcAttributeBeginEnd";
    size_t n = strlen(text);
    char *buf = malloc(n + 1);
    uint32_t rng = 12345u;
    for (int iter = 0; iter < 400; iter++) {
        memcpy(buf, text, n + 1);
        int edits = 1 + iter % 4;
        for (int e = 0; e < edits; e++) {
            rng = rng * 1664525u + 1013904223u;
            size_t at = (rng >> 8) % n;
            rng = rng * 1664525u + 1013904223u;
            buf[at] = alphabet[(rng >> 8) % (sizeof alphabet - 1)];
        }
        /* write the full n bytes: a NUL edit must reach the parser */
        FILE *f = fopen(tpath("mut.pbrt"), "wb");
        fwrite(buf, 1, n, f);
        fclose(f);
        pn_err err;
        pn_err_init(&err);
        struct pn_scene_s *s = NULL;
        pn_status st = pn_scene_parse(test_context(), tpath("mut.pbrt"), &s, &err);
        CHECK_MSG(st == PN_OK || st == PN_ERROR_BAD_INPUT || st == PN_ERROR_UNSUPPORTED, "iteration %d: %d %s", iter,
                  (int)st, err.message);
        CHECK((st == PN_OK) == (s != NULL));
        pn_scene_parse_free(s);
    }
    free(buf);
}

/* ---- the real scenes in ../shared/scenes ------------------------------------------------- */

static double seconds_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int compare_names(const void *a, const void *b) {
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

static void test_real_scenes(void) {
    char root[512];
    snprintf(root, sizeof root, "%s/scenes", PN_SHARED_DIR);
    DIR *d = opendir(root);
    if (!d) {
        pn_test_skip("../shared/scenes is not present");
        return;
    }
    char *names[256];
    int count = 0;
    struct dirent *e;
    while ((e = readdir(d)) && count < 256)
        if (e->d_name[0] != '.') names[count++] = strdup(e->d_name);
    closedir(d);
    qsort(names, (size_t)count, sizeof names[0], compare_names);
    double total = 0.0;
    int parsed = 0;
    for (int i = 0; i < count; i++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/%s/%s.pbrt", root, names[i], names[i]);
        if (access(path, R_OK) != 0) {
            /* no <folder>/<folder>.pbrt (e.g. killeroos): take the first .pbrt file in it */
            char dir[768];
            snprintf(dir, sizeof dir, "%s/%s", root, names[i]);
            DIR *sd = opendir(dir);
            path[0] = '\0';
            char *best = NULL;
            while (sd && (e = readdir(sd))) {
                size_t l = strlen(e->d_name);
                if (l > 5 && strcmp(e->d_name + l - 5, ".pbrt") == 0 && (!best || strcmp(e->d_name, best) < 0)) {
                    free(best);
                    best = strdup(e->d_name);
                }
            }
            if (sd) closedir(sd);
            if (best) snprintf(path, sizeof path, "%s/%s", dir, best);
            free(best);
            if (!path[0]) continue;
        }
        pn_err err;
        pn_err_init(&err);
        struct pn_scene_s *s = NULL;
        double t0 = seconds_now();
        pn_status st = pn_scene_parse(test_context(), path, &s, &err);
        double dt = seconds_now() - t0;
        total += dt;
        CHECK_MSG(st == PN_OK, "%s: %s", path, err.message);
        if (st != PN_OK) continue;
        parsed++;
        uint64_t tris = 0;
        for (int m = 0; m < s->mesh_count; m++) tris += s->meshes[m].triangle_count;
        int emitters = s->emission_count + s->light_def_count;
        fprintf(stderr, "    %-28s %7.3f s  %8llu triangles  %3d spheres  %4d emitters  %3d materials  %2d warnings\n",
                names[i], dt, (unsigned long long)tris, s->sphere_count, emitters, s->material_count,
                s->warnings.count);
        CHECK_MSG(tris > 0 || s->sphere_count > 0, "%s: no geometry", path);
        CHECK_MSG(emitters > 0, "%s: no lights", path);
        CHECK_MSG(s->material_count > 0, "%s: no materials", path);
        CHECK_MSG(s->camera.width > 0 && s->camera.height > 0, "%s: no resolution", path);
        CHECK_MSG(v3_is_finite(s->bounds_min) && v3_is_finite(s->bounds_max) && s->bounds_min.x < s->bounds_max.x,
                  "%s: bad bounds", path);
        for (int m = 0; m < s->mesh_count; m++) {
            const pn_mesh *mm = &s->meshes[m];
            CHECK(mm->material >= 0 && mm->material < s->material_count);
            CHECK(mm->emission < s->emission_count);
        }
        pn_scene_parse_free(s);
    }
    fprintf(stderr, "    %d scenes parsed in %.2f s\n", parsed, total);
    for (int i = 0; i < count; i++) free(names[i]);
}

static int remove_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw) {
    (void)st;
    (void)flag;
    (void)ftw;
    return remove(path);
}

/* Last: removes the temporary folder the tests wrote. */
static void test_cleanup(void) {
    CHECK(nftw(temp_dir(), remove_entry, 16, FTW_DEPTH | FTW_PHYS) == 0);
}

PN_TESTS(TEST(test_look_at_camera), TEST(test_transform_composition), TEST(test_coordinate_systems),
         TEST(test_attribute_scoping), TEST(test_default_material), TEST(test_reverse_orientation_and_handedness),
         TEST(test_attribute_defaults), TEST(test_include_relative), TEST(test_object_instances),
         TEST(test_trianglemesh_contents), TEST(test_disk_and_sphere), TEST(test_mirrored_disk),
         TEST(test_other_shapes), TEST(test_loop_subdivision), TEST(test_area_light), TEST(test_named_materials),
         TEST(test_unused_parameter_warning), TEST(test_motion_blur_warning), TEST(test_bad_input_table),
         TEST(test_recursive_include), TEST(test_missing_main_file), TEST(test_truncated_prefixes),
         TEST(test_mutations), TEST(test_real_scenes), TEST(test_cleanup))
