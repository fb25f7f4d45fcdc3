/* ias_mis.c — what ias's MIS with BSDF sampling needs from the scene and the lights (ias_mis.h). */
#include "integrators/ias_mis.h"

#include "lights/lights.h"
#include "scene/scene.h"

#include <stdlib.h>

pn_status pn_ias_mis_map_build(const pn_render_job *job, pn_ias_mis_map *map, pn_err *err) {
    const struct pn_scene_s *sc = job->scene;
    const pn_lights *L = job->lights;
    *map = (pn_ias_mis_map){0};
    int nm = sc->mesh_count > 0 ? sc->mesh_count : 1, ns = sc->sphere_count > 0 ? sc->sphere_count : 1;
    map->mesh_base = malloc((size_t)nm * sizeof *map->mesh_base);
    map->sphere_light = malloc((size_t)ns * sizeof *map->sphere_light);
    size_t tris = 0;
    for (int m = 0; m < sc->mesh_count; m++)
        if (sc->meshes[m].emission >= 0) tris += sc->meshes[m].triangle_count;
    map->tri_light = malloc((tris > 0 ? tris : 1) * sizeof *map->tri_light);
    if (!map->mesh_base || !map->sphere_light || !map->tri_light) {
        pn_ias_mis_map_free(map);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    size_t next = 0;
    for (int m = 0; m < sc->mesh_count; m++) {
        map->mesh_base[m] = -1;
        if (sc->meshes[m].emission < 0) continue;
        map->mesh_base[m] = (int)next;
        for (uint32_t t = 0; t < sc->meshes[m].triangle_count; t++) map->tri_light[next + t] = -1;
        next += sc->meshes[m].triangle_count;
    }
    for (int s = 0; s < ns; s++) map->sphere_light[s] = -1;
    for (int i = 0; i < L->count; i++) {
        const pn_light *l = &L->lights[i];
        if (l->kind == PN_LIGHT_SPHERE) {
            /* Sphere lights carry their sphere's centre and radius: match them back. */
            for (int s = 0; s < sc->sphere_count; s++)
                if (map->sphere_light[s] < 0 && sc->spheres[s].emission >= 0 && sc->spheres[s].radius == l->radius &&
                    sc->spheres[s].center.x == l->p.x && sc->spheres[s].center.y == l->p.y &&
                    sc->spheres[s].center.z == l->p.z) {
                    map->sphere_light[s] = i;
                    break;
                }
            continue;
        }
        if (l->mesh < 0 || l->mesh >= sc->mesh_count || map->mesh_base[l->mesh] < 0) continue;
        const pn_mesh *m = &sc->meshes[l->mesh];
        int *slot = map->tri_light + map->mesh_base[l->mesh];
        if (l->kind == PN_LIGHT_DISK) { /* the disk's whole mesh */
            for (uint32_t t = 0; t < m->triangle_count; t++) slot[t] = i;
        } else if (l->kind == PN_LIGHT_TRIANGLE && l->prim >= 0 && (uint32_t)l->prim < m->triangle_count) {
            slot[l->prim] = i;
        } else if (l->kind == PN_LIGHT_RECTANGLE && l->prim >= 0 && (uint32_t)l->prim < m->triangle_count) {
            slot[l->prim] = i; /* a rectangle is the triangle pair prim, prim + 1 */
            if ((uint32_t)l->prim + 1 < m->triangle_count) slot[l->prim + 1] = i;
        }
    }
    return PN_OK;
}

void pn_ias_mis_map_free(pn_ias_mis_map *map) {
    free(map->mesh_base);
    free(map->tri_light);
    free(map->sphere_light);
    *map = (pn_ias_mis_map){0};
}

int pn_ias_mis_light_of_hit(const pn_ias_mis_map *map, const pn_hit *hit) {
    if (hit->emission < 0 || hit->instance >= 0) return -1;
    if (hit->sphere >= 0) return map->sphere_light[hit->sphere];
    if (hit->mesh < 0 || map->mesh_base[hit->mesh] < 0) return -1;
    return map->tri_light[map->mesh_base[hit->mesh] + (int)hit->prim];
}

bool pn_ias_mis_trace(const pn_render_job *job, vec3 o, vec3 wi, pn_hit *hit, float *trans) {
    *trans = 1.0f;
    if (job->opaque_glass || !pn_accel_has_thin_glass(job->accel))
        return pn_accel_intersect(job->accel, o, wi, 0.0f, INFINITY, hit);
    const bool surface = pn_accel_intersect_opaque(job->accel, o, wi, 0.0f, INFINITY, hit);
    *trans = pn_shadow_transmittance(job, o, wi, 0.0f, surface ? hit->t * (1.0f - 1e-4f) : INFINITY);
    return surface;
}
