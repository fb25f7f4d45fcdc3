/* scene_load.c — the public scene API: parse, build light records and the BVH, report. */
#include "accel/accel.h"
#include "core/clock.h"
#include "core/context.h"
#include "lights/lights.h"
#include "scene/scene.h"

#include <stdlib.h>
#include <string.h>

pn_status pn_scene_load(pn_context ctx, const char *path, pn_scene *out_scene) {
    if (out_scene) *out_scene = NULL;
    if (!ctx || !path || !out_scene) {
        if (ctx) pn_context_fail(ctx, PN_ERROR_INVALID_ARGUMENT, "pn_scene_load: NULL argument");
        return PN_ERROR_INVALID_ARGUMENT;
    }
    pn_err err;
    pn_err_init(&err);
    struct pn_scene_s *scene = NULL;
    double t0 = pn_clock_seconds();
    pn_status st = pn_scene_parse(ctx, path, &scene, &err);
    if (st != PN_OK) return pn_context_fail_from(ctx, &err);
    scene->parse_seconds = pn_clock_seconds() - t0;
    st = pn_lights_build(scene, &scene->lights, &err);
    if (st == PN_OK) {
        double t1 = pn_clock_seconds();
        st = pn_accel_build(scene, &scene->accel, &err);
        scene->bvh_seconds = pn_clock_seconds() - t1;
    }
    if (st != PN_OK) {
        pn_scene_free(scene);
        return pn_context_fail_from(ctx, &err);
    }
    *out_scene = scene;
    return PN_OK;
}

void pn_scene_free(pn_scene scene) {
    if (!scene) return;
    pn_accel_free(scene->accel);
    pn_lights_free(scene->lights);
    scene->accel = NULL;
    scene->lights = NULL;
    pn_scene_parse_free(scene);
}

pn_status pn_scene_get_info(pn_scene scene, pn_scene_info *info) {
    if (!scene || !info) return PN_ERROR_INVALID_ARGUMENT;
    memset(info, 0, sizeof *info);
    uint64_t unique = 0, total = 0;
    for (int i = 0; i < scene->mesh_count; i++) {
        const pn_mesh *m = &scene->meshes[i];
        unique += m->triangle_count;
        if (m->object < 0) total += m->triangle_count;
    }
    for (int k = 0; k < scene->instance_count; k++) {
        int o = scene->instances[k].object;
        if (o < 0 || o >= scene->object_count) continue;
        const pn_object *ob = &scene->objects[o];
        for (int j = 0; j < ob->mesh_count; j++) total += scene->meshes[ob->first_mesh + j].triangle_count;
    }
    info->triangles = total;
    info->unique_triangles = unique;
    info->meshes = (uint32_t)scene->mesh_count;
    info->instances = (uint32_t)scene->instance_count;
    info->spheres = (uint32_t)scene->sphere_count;
    const pn_lights *L = scene->lights;
    if (L) {
        info->lights_point = (uint32_t)L->count_by_kind[PN_LIGHT_POINT];
        info->lights_spot = (uint32_t)L->count_by_kind[PN_LIGHT_SPOT];
        info->lights_distant = (uint32_t)L->count_by_kind[PN_LIGHT_DISTANT];
        info->lights_infinite = (uint32_t)L->count_by_kind[PN_LIGHT_ENVIRONMENT];
        info->lights_area_triangle = (uint32_t)L->count_by_kind[PN_LIGHT_TRIANGLE];
        info->lights_area_rectangle = (uint32_t)L->count_by_kind[PN_LIGHT_RECTANGLE];
        info->lights_area_disk = (uint32_t)L->count_by_kind[PN_LIGHT_DISK];
        info->lights_area_sphere = (uint32_t)L->count_by_kind[PN_LIGHT_SPHERE];
        info->lights_goniometric = (uint32_t)L->count_by_kind[PN_LIGHT_GONIOMETRIC];
        info->lights_projection = (uint32_t)L->count_by_kind[PN_LIGHT_PROJECTION];
    }
    info->materials = (uint32_t)scene->material_count;
    info->textures = (uint32_t)scene->texture_count;
    info->texture_images = (uint32_t)scene->image_count;
    for (int i = 0; i < scene->image_count; i++) /* issue 19: what the decoded images cost */
        info->texture_bytes += (uint64_t)scene->images[i].width * (uint64_t)scene->images[i].height * 3 * sizeof(float);
    for (int i = 0; i < scene->mipmap_count; i++) /* and the image textures' pyramids (scene/mipmap.c) */
        for (int l = 0; l < scene->mipmaps[i].levels; l++)
            info->texture_bytes += (uint64_t)scene->mipmaps[i].level[l].width *
                                   (uint64_t)scene->mipmaps[i].level[l].height * 3 * sizeof(float);
    info->warnings = (uint32_t)scene->warnings.count;
    info->bounds_min[0] = scene->bounds_min.x;
    info->bounds_min[1] = scene->bounds_min.y;
    info->bounds_min[2] = scene->bounds_min.z;
    info->bounds_max[0] = scene->bounds_max.x;
    info->bounds_max[1] = scene->bounds_max.y;
    info->bounds_max[2] = scene->bounds_max.z;
    info->resolution[0] = scene->camera.width;
    info->resolution[1] = scene->camera.height;
    info->parse_seconds = scene->parse_seconds;
    info->bvh_seconds = scene->bvh_seconds;
    return PN_OK;
}

uint32_t pn_scene_vpl_depth(const struct pn_scene_s *scene, uint32_t fallback) {
    if (!scene || !scene->camera.max_depth_given) return fallback;
    return scene->camera.max_depth > 1 ? (uint32_t)(scene->camera.max_depth - 1) : 0u;
}

uint32_t pn_scene_material_count(pn_scene scene) {
    return scene ? (uint32_t)scene->material_count : 0;
}

const char *pn_scene_material_description(pn_scene scene, uint32_t index) {
    if (!scene || index >= (uint32_t)scene->material_count) return "";
    const char *d = scene->materials[index].description;
    return d ? d : "";
}

uint32_t pn_scene_warning_count(pn_scene scene) {
    return scene ? (uint32_t)scene->warnings.count : 0;
}

const char *pn_scene_warning(pn_scene scene, uint32_t index) {
    if (!scene || index >= (uint32_t)scene->warnings.count) return "";
    return scene->warnings.items[index];
}
