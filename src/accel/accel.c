/* accel.c — Embree 3 scene construction (triangles, spheres as RTC_GEOMETRY_TYPE_SPHERE_POINT,
 * instances) and single-ray queries, with alpha cut-outs done in Embree filter callbacks.
 *
 * Ray masks: bit 0 (0x1) eye and light-path rays, bit 1 (0x2) opaque shadow blockers, bit 2 (0x4)
 * thin glass panes (meshes and spheres whose material is a thin dielectric). Plain occlusion queries use 0x6,
 * so that panes block them as before; pn_accel_transmittance asks 0x2 and then walks the panes
 * (0x4) along the ray, multiplying their slab transmittance (glass.c describes the optics). */
#include "accel/accel.h"

#include "core/optics.h"
#include "core/rng.h"

#include "scene/scene.h"

#include <embree3/rtcore.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* What an Embree geometry id stands for. */
typedef struct geom_ref {
    int kind;         /* 0 = mesh, 1 = sphere set, 2 = instance */
    int index;        /* mesh index, or instance index */
    int first_sphere; /* for sphere sets: scene sphere index of primitive 0 */
} geom_ref;

typedef struct scene_table {
    RTCScene rtc;
    geom_ref *refs;
    int ref_count;
} scene_table;

struct pn_accel {
    const struct pn_scene_s *scene;
    RTCDevice device;
    scene_table world;
    scene_table *objects; /* one per scene object */
    int object_count;
    float epsilon_base;
    bool thin_glass; /* some mesh or sphere is a thin glass pane (mask 0x4) */
};

/* Alpha filter: per-geometry user data. */
typedef struct alpha_user {
    const struct pn_scene_s *scene;
    const pn_mesh *mesh;
} alpha_user;

static void alpha_filter(const struct RTCFilterFunctionNArguments *args) {
    const alpha_user *au = args->geometryUserPtr;
    const pn_mesh *m = au->mesh;
    unsigned N = args->N;
    float *hit = (float *)args->hit;
    const float *ray = (const float *)args->ray;
    for (unsigned i = 0; i < N; i++) {
        if (args->valid[i] != -1) continue;
        unsigned prim = ((unsigned *)hit)[5 * N + i];
        float bu = hit[3 * N + i], bv = hit[4 * N + i];
        float s = bu, t = bv;
        if (m->uvs) {
            const uint32_t *idx = m->indices + 3 * (size_t)prim;
            const float *a = m->uvs + 2 * (size_t)idx[0], *b = m->uvs + 2 * (size_t)idx[1],
                        *c = m->uvs + 2 * (size_t)idx[2];
            float w = 1.0f - bu - bv;
            s = w * a[0] + bu * b[0] + bv * c[0];
            t = w * a[1] + bu * b[1] + bv * c[1];
        }
        float alpha = pn_texture_eval(au->scene, m->alpha, s, t).x;
        if (alpha >= 1.0f) continue;
        if (alpha <= 0.0f) {
            args->valid[i] = 0;
            continue;
        }
        /* Stochastic transparency as pbrt-v4 does it: a hash of the ray decides, so the same ray
         * always sees the same answer whatever the thread. */
        uint32_t h1, h2;
        float ox = ray[0 * N + i], dx = ray[4 * N + i], dy = ray[5 * N + i];
        memcpy(&h1, &ox, 4);
        float mix = dx * 0.7f + dy * 0.3f;
        memcpy(&h2, &mix, 4);
        if (pn_hash_unit(pn_hash3(h1, prim, h2)) > alpha) args->valid[i] = 0;
    }
}

static pn_status add_ref(scene_table *tab, unsigned id, geom_ref ref, pn_err *err) {
    if ((int)id >= tab->ref_count) {
        int n = (int)id + 1;
        geom_ref *nr = realloc(tab->refs, (size_t)n * sizeof *nr);
        if (!nr) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory building the BVH");
        for (int i = tab->ref_count; i < n; i++) nr[i] = (geom_ref){-1, -1, -1};
        tab->refs = nr;
        tab->ref_count = n;
    }
    tab->refs[id] = ref;
    return PN_OK;
}

static pn_status add_mesh(pn_accel *acc, scene_table *tab, int mesh_index, pn_err *err) {
    const struct pn_scene_s *scene = acc->scene;
    const pn_mesh *m = &scene->meshes[mesh_index];
    if (m->triangle_count == 0 || m->vertex_count == 0) return PN_OK;
    RTCGeometry g = rtcNewGeometry(acc->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "Embree could not create a geometry");
    float *vb =
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->vertex_count);
    unsigned *ib =
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->triangle_count);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for mesh %s", m->source ? m->source : "");
    }
    memcpy(vb, m->positions, (size_t)m->vertex_count * 3 * sizeof(float));
    memcpy(ib, m->indices, (size_t)m->triangle_count * 3 * sizeof(unsigned));
    const pn_material *mat =
        (m->material >= 0 && m->material < scene->material_count) ? &scene->materials[m->material] : NULL;
    bool has_alpha = m->alpha.texture >= 0 || m->alpha.value.x < 1.0f;
    alpha_user *au = NULL;
    if (has_alpha) {
        au = malloc(sizeof *au);
        if (!au) {
            rtcReleaseGeometry(g);
            return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        }
        au->scene = scene;
        au->mesh = m;
        rtcSetGeometryUserData(g, au);
        rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
        rtcSetGeometryOccludedFilterFunction(g, alpha_filter);
    }
    /* Geometry mask: bit 1 = blocks shadow rays; interface materials block nothing. */
    unsigned mask = 0x3;
    if (mat && mat->kind == PN_MATERIAL_INTERFACE) mask = 0x0;
    if (mat && mat->kind == PN_MATERIAL_DIELECTRIC && mat->thin) {
        mask = 0x5; /* seen by eye rays; a pane, not an opaque blocker, to shadow rays */
        acc->thin_glass = true;
    }
    rtcSetGeometryMask(g, mask);
    rtcCommitGeometry(g);
    unsigned id = rtcAttachGeometry(tab->rtc, g);
    rtcReleaseGeometry(g);
    if (au) {
        /* Keep the pointer for freeing: store in a ref of its own kind. */
    }
    return add_ref(tab, id, (geom_ref){0, mesh_index, -1}, err);
}

/* Whether sphere i's material is a thin glass pane (thindielectric, or dielectric marked thin). */
static bool sphere_is_thin_glass(const struct pn_scene_s *scene, int i) {
    int m = scene->spheres[i].material;
    return m >= 0 && m < scene->material_count && scene->materials[m].kind == PN_MATERIAL_DIELECTRIC &&
           scene->materials[m].thin;
}

static pn_status add_sphere_run(pn_accel *acc, scene_table *tab, int first, int count, bool thin, pn_err *err);

/* Spheres first .. first + count - 1, as one Embree geometry per run of equal glazing (a run of
 * thin-glass spheres carries the panes' mask, so that shadow rays pass it attenuated). */
static pn_status add_spheres(pn_accel *acc, scene_table *tab, int first, int count, pn_err *err) {
    for (int i = first; i < first + count;) {
        bool thin = sphere_is_thin_glass(acc->scene, i);
        int j = i + 1;
        while (j < first + count && sphere_is_thin_glass(acc->scene, j) == thin) j++;
        pn_status st = add_sphere_run(acc, tab, i, j - i, thin, err);
        if (st != PN_OK) return st;
        i = j;
    }
    return PN_OK;
}

static pn_status add_sphere_run(pn_accel *acc, scene_table *tab, int first, int count, bool thin, pn_err *err) {
    if (count <= 0) return PN_OK;
    const struct pn_scene_s *scene = acc->scene;
    RTCGeometry g = rtcNewGeometry(acc->device, RTC_GEOMETRY_TYPE_SPHERE_POINT);
    if (!g) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "Embree could not create a geometry");
    float *vb =
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT4, 4 * sizeof(float), (size_t)count);
    if (!vb) {
        rtcReleaseGeometry(g);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for spheres");
    }
    for (int i = 0; i < count; i++) {
        const pn_sphere *s = &scene->spheres[first + i];
        vb[4 * i + 0] = s->center.x;
        vb[4 * i + 1] = s->center.y;
        vb[4 * i + 2] = s->center.z;
        vb[4 * i + 3] = s->radius;
    }
    rtcSetGeometryMask(g, thin ? 0x5 : 0x3);
    if (thin) acc->thin_glass = true;
    rtcCommitGeometry(g);
    unsigned id = rtcAttachGeometry(tab->rtc, g);
    rtcReleaseGeometry(g);
    return add_ref(tab, id, (geom_ref){1, -1, first}, err);
}

static void free_alpha_users(RTCScene rtc, const scene_table *tab) {
    for (int i = 0; i < tab->ref_count; i++) {
        if (tab->refs[i].kind != 0) continue;
        RTCGeometry g = rtcGetGeometry(rtc, (unsigned)i);
        if (g) free(rtcGetGeometryUserData(g));
    }
}

void pn_accel_free(pn_accel *acc) {
    if (!acc) return;
    if (acc->world.rtc) {
        free_alpha_users(acc->world.rtc, &acc->world);
        rtcReleaseScene(acc->world.rtc);
    }
    free(acc->world.refs);
    for (int i = 0; i < acc->object_count; i++) {
        if (acc->objects[i].rtc) {
            free_alpha_users(acc->objects[i].rtc, &acc->objects[i]);
            rtcReleaseScene(acc->objects[i].rtc);
        }
        free(acc->objects[i].refs);
    }
    free(acc->objects);
    if (acc->device) rtcReleaseDevice(acc->device);
    free(acc);
}

pn_status pn_accel_build(struct pn_scene_s *scene, pn_accel **out, pn_err *err) {
    *out = NULL;
    pn_accel *acc = calloc(1, sizeof *acc);
    if (!acc) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    acc->scene = scene;
    acc->device = rtcNewDevice("verbose=0");
    if (!acc->device) {
        free(acc);
        return pn_err_set(err, PN_ERROR_INTERNAL, "Embree device creation failed (error %d)",
                          (int)rtcGetDeviceError(NULL));
    }
    pn_status st = PN_OK;
    acc->world.rtc = rtcNewScene(acc->device);
    rtcSetSceneBuildQuality(acc->world.rtc, RTC_BUILD_QUALITY_HIGH);
    if (scene->object_count > 0) {
        acc->objects = calloc((size_t)scene->object_count, sizeof *acc->objects);
        if (!acc->objects)
            st = pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
        else
            acc->object_count = scene->object_count;
    }
    for (int i = 0; st == PN_OK && i < scene->mesh_count; i++) {
        int obj = scene->meshes[i].object;
        if (obj >= 0) continue;
        st = add_mesh(acc, &acc->world, i, err);
    }
    /* World spheres form one contiguous run per object id; gather runs of object == -1. */
    for (int i = 0; st == PN_OK && i < scene->sphere_count;) {
        int j = i;
        while (j < scene->sphere_count && scene->spheres[j].object == scene->spheres[i].object) j++;
        if (scene->spheres[i].object < 0) st = add_spheres(acc, &acc->world, i, j - i, err);
        i = j;
    }
    for (int o = 0; st == PN_OK && o < acc->object_count; o++) {
        const pn_object *ob = &scene->objects[o];
        scene_table *tab = &acc->objects[o];
        tab->rtc = rtcNewScene(acc->device);
        for (int k = 0; st == PN_OK && k < ob->mesh_count; k++) st = add_mesh(acc, tab, ob->first_mesh + k, err);
        if (st == PN_OK) st = add_spheres(acc, tab, ob->first_sphere, ob->sphere_count, err);
        if (st == PN_OK) rtcCommitScene(tab->rtc);
    }
    for (int k = 0; st == PN_OK && k < scene->instance_count; k++) {
        const pn_instance *in = &scene->instances[k];
        if (in->object < 0 || in->object >= acc->object_count) continue;
        RTCGeometry g = rtcNewGeometry(acc->device, RTC_GEOMETRY_TYPE_INSTANCE);
        rtcSetGeometryInstancedScene(g, acc->objects[in->object].rtc);
        float xf[12]; /* column-major 3x4 */
        for (int c = 0; c < 4; c++)
            for (int r = 0; r < 3; r++) xf[c * 3 + r] = (float)in->world_from_object.m[r][c];
        rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, xf);
        rtcSetGeometryMask(g, 0x7);
        rtcCommitGeometry(g);
        unsigned id = rtcAttachGeometry(acc->world.rtc, g);
        rtcReleaseGeometry(g);
        st = add_ref(&acc->world, id, (geom_ref){2, k, -1}, err);
    }
    if (st == PN_OK) {
        rtcCommitScene(acc->world.rtc);
        enum RTCError e = rtcGetDeviceError(acc->device);
        if (e != RTC_ERROR_NONE)
            st = pn_err_set(err, e == RTC_ERROR_OUT_OF_MEMORY ? PN_ERROR_OUT_OF_MEMORY : PN_ERROR_INTERNAL,
                            "Embree failed to build the scene (error %d)", (int)e);
    }
    if (st != PN_OK) {
        pn_accel_free(acc);
        return st;
    }
    vec3 ext = v3_sub(scene->bounds_max, scene->bounds_min);
    float diag = v3_length(ext);
    if (!(diag > 0.0f) || !isfinite(diag)) diag = 1.0f;
    acc->epsilon_base = diag;
    *out = acc;
    return PN_OK;
}

float pn_accel_ray_epsilon(const pn_accel *acc, vec3 p) {
    float m = fmaxf(fabsf(p.x), fmaxf(fabsf(p.y), fabsf(p.z)));
    return fmaxf(1e-5f * fminf(acc->epsilon_base, 1e6f), 4e-6f * m);
}

static void fill_triangle_hit(const struct pn_scene_s *scene, const pn_mesh *m, unsigned prim, float bu, float bv,
                              const mat4 *xf, const mat4 *xf_inv, pn_hit *h) {
    const uint32_t *idx = m->indices + 3 * (size_t)prim;
    vec3 p0 = v3(m->positions[3 * idx[0]], m->positions[3 * idx[0] + 1], m->positions[3 * idx[0] + 2]);
    vec3 p1 = v3(m->positions[3 * idx[1]], m->positions[3 * idx[1] + 1], m->positions[3 * idx[1] + 2]);
    vec3 p2 = v3(m->positions[3 * idx[2]], m->positions[3 * idx[2] + 1], m->positions[3 * idx[2] + 2]);
    vec3 ng = v3_normalize(v3_cross(v3_sub(p1, p0), v3_sub(p2, p0)));
    bool flip = m->flip_normals;
    if (xf && mat4_det3(xf) < 0.0) flip = !flip;
    if (flip) ng = v3_neg(ng);
    float w = 1.0f - bu - bv;
    vec3 ns = ng;
    if (m->normals) {
        const float *n0 = m->normals + 3 * (size_t)idx[0], *n1 = m->normals + 3 * (size_t)idx[1],
                    *n2 = m->normals + 3 * (size_t)idx[2];
        vec3 n = v3(w * n0[0] + bu * n1[0] + bv * n2[0], w * n0[1] + bu * n1[1] + bv * n2[1],
                    w * n0[2] + bu * n1[2] + bv * n2[2]);
        if (v3_length2(n) > 0.0f) {
            ns = v3_normalize(n);
            if (v3_dot(ng, ns) < 0.0f) ng = v3_neg(ng);
        }
    }
    if (m->uvs) {
        const float *a = m->uvs + 2 * (size_t)idx[0], *b = m->uvs + 2 * (size_t)idx[1],
                    *c = m->uvs + 2 * (size_t)idx[2];
        h->u = w * a[0] + bu * b[0] + bv * c[0];
        h->v = w * a[1] + bu * b[1] + bv * c[1];
    } else {
        /* pbrt's default parametrisation: (0,0), (1,0), (1,1) at the three vertices. */
        h->u = bu + bv;
        h->v = bv;
    }
    if (xf) {
        ng = v3_normalize(mat4_apply_normal(xf_inv, ng));
        ns = v3_normalize(mat4_apply_normal(xf_inv, ns));
    }
    h->ng = ng;
    h->ns = ns;
    h->material = m->material;
    h->emission = m->emission;
    (void)scene;
}

bool pn_accel_has_thin_glass(const pn_accel *acc) {
    return acc->thin_glass;
}

static bool intersect_mask(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, unsigned mask, pn_hit *h);

bool pn_accel_intersect(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, pn_hit *h) {
    return intersect_mask(acc, o, d, tmin, tmax, 0x1, h);
}

bool pn_accel_intersect_opaque(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, pn_hit *h) {
    return intersect_mask(acc, o, d, tmin, tmax, 0x2, h);
}

static bool intersect_mask(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, unsigned mask, pn_hit *h) {
    struct RTCIntersectContext ictx;
    rtcInitIntersectContext(&ictx);
    struct RTCRayHit rh;
    rh.ray.org_x = o.x;
    rh.ray.org_y = o.y;
    rh.ray.org_z = o.z;
    rh.ray.tnear = tmin;
    rh.ray.dir_x = d.x;
    rh.ray.dir_y = d.y;
    rh.ray.dir_z = d.z;
    rh.ray.time = 0.0f;
    rh.ray.tfar = tmax;
    rh.ray.mask = mask;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(acc->world.rtc, &ictx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    const struct pn_scene_s *scene = acc->scene;
    const scene_table *tab = &acc->world;
    const mat4 *xf = NULL;
    mat4 inv;
    h->instance = -1;
    if (rh.hit.instID[0] != RTC_INVALID_GEOMETRY_ID) {
        const geom_ref *ir = &acc->world.refs[rh.hit.instID[0]];
        const pn_instance *in = &scene->instances[ir->index];
        tab = &acc->objects[in->object];
        xf = &in->world_from_object;
        if (!mat4_inverse(*xf, &inv)) inv = mat4_identity();
        h->instance = ir->index;
    }
    const geom_ref *r = &tab->refs[rh.hit.geomID];
    h->t = rh.ray.tfar;
    h->p = v3_madd(o, d, rh.ray.tfar);
    h->duv[0] = h->duv[1] = h->duv[2] = h->duv[3] = 0.0f;
    h->prim = rh.hit.primID;
    if (r->kind == 0) {
        h->mesh = r->index;
        h->sphere = -1;
        fill_triangle_hit(scene, &scene->meshes[r->index], rh.hit.primID, rh.hit.u, rh.hit.v, xf, &inv, h);
    } else {
        int si = r->first_sphere + (int)rh.hit.primID;
        const pn_sphere *s = &scene->spheres[si];
        h->mesh = -1;
        h->sphere = si;
        vec3 c = s->center;
        if (xf) c = mat4_apply_point(xf, c);
        vec3 n = v3_normalize(v3_sub(h->p, c));
        /* Project the point onto the sphere to remove the intersection error. */
        float rad = s->radius;
        if (xf) rad *= (float)cbrt(fabs(mat4_det3(xf)));
        h->p = v3_madd(c, n, rad);
        bool flip = s->flip_normals;
        if (xf && mat4_det3(xf) < 0.0) flip = !flip;
        if (flip) n = v3_neg(n);
        h->ng = n;
        h->ns = n;
        /* pbrt-v4's sphere (u, v) in object space: u = phi / 2pi, v = (theta - theta_zmin) /
         * (theta_zmax - theta_zmin) with theta_zmin = acos(zmin / r) = pi and theta_zmax = 0 for
         * the full sphere: v = 1 - theta / pi (v = 0 at the object's -z pole). */
        vec3 ln = v3_sub(h->p, c);
        if (xf) ln = mat4_apply_vector(&inv, ln);
        ln = v3_normalize(ln);
        vec3 lo = v3(v3_dot(ln, s->axis[0]), v3_dot(ln, s->axis[1]), v3_dot(ln, s->axis[2]));
        float phi = atan2f(lo.y, lo.x);
        if (phi < 0.0f) phi += 2.0f * PN_PI;
        h->u = phi / (2.0f * PN_PI);
        h->v = 1.0f - acosf(fminf(1.0f, fmaxf(-1.0f, lo.z))) / PN_PI;
        h->material = s->material;
        h->emission = s->emission;
    }
    return true;
}

static bool occluded_mask(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, unsigned mask);

bool pn_accel_occluded(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax) {
    return occluded_mask(acc, o, d, tmin, tmax, 0x6);
}

/* The panes crossed by o + t d for t in (tmin, tmax), each multiplying the transmittance. */
static float glass_walk(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax) {
    float transmittance = 1.0f;
    const float inv_len = 1.0f / v3_length(d);
    vec3 du = v3_scale(d, inv_len);
    pn_hit h;
    /* A bound on the panes counted, against rays that graze a pane along its own plane. */
    for (int crossings = 0; crossings < PN_ACCEL_MAX_PANES && tmin < tmax; crossings++) {
        if (!intersect_mask(acc, o, d, tmin, tmax, 0x4, &h)) break;
        const pn_material *m = &acc->scene->materials[h.material];
        transmittance *= pn_thin_glass_transmittance(fabsf(v3_dot(du, h.ng)), m->eta);
        if (!(transmittance > 0.0f)) return 0.0f;
        tmin = h.t + pn_accel_ray_epsilon(acc, h.p) * inv_len;
    }
    return transmittance;
}

float pn_accel_transmittance(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax) {
    if (occluded_mask(acc, o, d, tmin, tmax, 0x2)) return 0.0f;
    return acc->thin_glass ? glass_walk(acc, o, d, tmin, tmax) : 1.0f;
}

static bool occluded_mask(const pn_accel *acc, vec3 o, vec3 d, float tmin, float tmax, unsigned mask) {
    struct RTCIntersectContext ictx;
    rtcInitIntersectContext(&ictx);
    struct RTCRay ray;
    ray.org_x = o.x;
    ray.org_y = o.y;
    ray.org_z = o.z;
    ray.tnear = tmin;
    ray.dir_x = d.x;
    ray.dir_y = d.y;
    ray.dir_z = d.z;
    ray.time = 0.0f;
    ray.tfar = tmax;
    ray.mask = mask;
    ray.id = 0;
    ray.flags = 0;
    rtcOccluded1(acc->world.rtc, &ictx, &ray);
    return ray.tfar < 0.0f;
}

/* Up to 16 occlusion rays traced as one Embree packet of the smallest native width that holds
 * them (one ray: rtcOccluded1). The ray records are the same as pn_accel_occluded's, and the
 * answers are its answers (test_illumcut compares them on random rays) except for rays that
 * pass exactly through a triangle edge: Embree's packet and single-ray triangle tests differ
 * there (ics12: 1 ray in ~10^8 of illumcut's shadow rays, a directional VPL's ray through a
 * shared edge at u + v = 1, found free by the packet and occluded by rtcOccluded1). */
static void occluded_packet_mask(const pn_accel *acc, int count, const vec3 *o, const vec3 *d, const float *tmin,
                                 const float *tmax, unsigned mask, bool *occluded);

void pn_accel_occluded_packet(const pn_accel *acc, int count, const vec3 *o, const vec3 *d, const float *tmin,
                              const float *tmax, bool *occluded) {
    occluded_packet_mask(acc, count, o, d, tmin, tmax, 0x6, occluded);
}

void pn_accel_transmittance_packet(const pn_accel *acc, int count, const vec3 *o, const vec3 *d, const float *tmin,
                                   const float *tmax, float *transmittance) {
    for (int base = 0; base < count; base += 16) {
        int n = count - base < 16 ? count - base : 16;
        bool occluded[16];
        occluded_packet_mask(acc, n, o + base, d + base, tmin + base, tmax + base, 0x2, occluded);
        for (int i = 0; i < n; i++) {
            int k = base + i;
            transmittance[k] = occluded[i]       ? 0.0f
                               : acc->thin_glass ? glass_walk(acc, o[k], d[k], tmin[k], tmax[k])
                                                 : 1.0f;
        }
    }
}

static void occluded_packet_mask(const pn_accel *acc, int count, const vec3 *o, const vec3 *d, const float *tmin,
                                 const float *tmax, unsigned mask, bool *occluded) {
    if (count <= 0) return;
    if (count == 1) {
        occluded[0] = occluded_mask(acc, o[0], d[0], tmin[0], tmax[0], mask);
        return;
    }
    if (count > 16) {
        occluded_packet_mask(acc, 16, o, d, tmin, tmax, mask, occluded);
        occluded_packet_mask(acc, count - 16, o + 16, d + 16, tmin + 16, tmax + 16, mask, occluded + 16);
        return;
    }
    /* The context stays incoherent (the default): with RTC_INTERSECT_CONTEXT_FLAG_COHERENT,
     * Embree 3.13.5's packet traversal reported ~10 in 34 million of these rays (bathroom, shadow
     * rays of IC-S) occluded that rtcOccluded1 and rtcIntersect4 found free. */
    struct RTCIntersectContext ictx;
    rtcInitIntersectContext(&ictx);
    int width = count <= 4 ? 4 : count <= 8 ? 8 : 16;
    /* RTCRay16 is the largest layout; the 4- and 8-wide ones are the same fields with stride 4
     * and 8, so the record is filled through a float view with stride `width`. */
    struct RTCRay16 ray __attribute__((aligned(64)));
    int valid[16] __attribute__((aligned(64)));
    float *f = (float *)&ray;
    unsigned *u = (unsigned *)&ray;
    for (int i = 0; i < width; i++) {
        bool on = i < count;
        valid[i] = on ? -1 : 0;
        int j = on ? i : 0;
        f[0 * width + i] = o[j].x;
        f[1 * width + i] = o[j].y;
        f[2 * width + i] = o[j].z;
        f[3 * width + i] = tmin[j];
        f[4 * width + i] = d[j].x;
        f[5 * width + i] = d[j].y;
        f[6 * width + i] = d[j].z;
        f[7 * width + i] = 0.0f;    /* time */
        f[8 * width + i] = tmax[j]; /* tfar */
        u[9 * width + i] = mask;
        u[10 * width + i] = 0; /* id */
        u[11 * width + i] = 0; /* flags */
    }
    if (width == 4)
        rtcOccluded4(valid, acc->world.rtc, &ictx, (struct RTCRay4 *)&ray);
    else if (width == 8)
        rtcOccluded8(valid, acc->world.rtc, &ictx, (struct RTCRay8 *)&ray);
    else
        rtcOccluded16(valid, acc->world.rtc, &ictx, &ray);
    for (int i = 0; i < count; i++) occluded[i] = f[8 * width + i] < 0.0f;
}

/* pbrt-v4 CoordinateSystem: two unit vectors completing unit n to an orthonormal frame. */
static void coordinate_system(vec3 n, vec3 *a, vec3 *b) {
    float sign = copysignf(1.0f, n.z);
    float k = -1.0f / (sign + n.z);
    float c = n.x * n.y * k;
    *a = v3(1.0f + sign * n.x * n.x * k, sign * c, -sign * n.x);
    *b = v3(c, sign + n.y * n.y * k, -n.y);
}

bool pn_accel_hit_uv_partials(const pn_accel *acc, const pn_hit *h, vec3 *dpdu, vec3 *dpdv) {
    const struct pn_scene_s *scene = acc->scene;
    if (h->mesh < 0 || h->mesh >= scene->mesh_count) return false;
    const pn_mesh *m = &scene->meshes[h->mesh];
    const uint32_t *idx = m->indices + 3 * (size_t)h->prim;
    vec3 p[3];
    float uv[3][2] = {{0, 0}, {1, 0}, {1, 1}};
    for (int k = 0; k < 3; k++) {
        const float *q = m->positions + 3 * (size_t)idx[k];
        p[k] = v3(q[0], q[1], q[2]);
        if (m->uvs) {
            uv[k][0] = m->uvs[2 * (size_t)idx[k]];
            uv[k][1] = m->uvs[2 * (size_t)idx[k] + 1];
        }
    }
    float duv02[2] = {uv[0][0] - uv[2][0], uv[0][1] - uv[2][1]}, duv12[2] = {uv[1][0] - uv[2][0], uv[1][1] - uv[2][1]};
    vec3 dp02 = v3_sub(p[0], p[2]), dp12 = v3_sub(p[1], p[2]);
    float det = duv02[0] * duv12[1] - duv02[1] * duv12[0];
    bool degenerate = fabsf(det) < 1e-9f;
    vec3 a = v3(0, 0, 0), b = v3(0, 0, 0);
    if (!degenerate) {
        float inv = 1.0f / det;
        a = v3_scale(v3_sub(v3_scale(dp02, duv12[1]), v3_scale(dp12, duv02[1])), inv);
        b = v3_scale(v3_sub(v3_scale(dp12, duv02[0]), v3_scale(dp02, duv12[0])), inv);
    }
    if (degenerate || v3_length2(v3_cross(a, b)) == 0.0f) {
        vec3 n = v3_cross(v3_sub(p[2], p[0]), v3_sub(p[1], p[0]));
        if (!(v3_length2(n) > 0.0f)) return false;
        coordinate_system(v3_normalize(n), &a, &b);
    }
    if (h->instance >= 0) {
        const mat4 *xf = &scene->instances[h->instance].world_from_object;
        a = mat4_apply_vector(xf, a);
        b = mat4_apply_vector(xf, b);
    }
    *dpdu = a;
    *dpdv = b;
    return true;
}

void pn_hit_uv_footprint(const pn_accel *acc, pn_hit *h, vec3 ox, vec3 dx, vec3 oy, vec3 dy) {
    vec3 dpdu, dpdv;
    h->duv[0] = h->duv[1] = h->duv[2] = h->duv[3] = 0.0f;
    if (!pn_accel_hit_uv_partials(acc, h, &dpdu, &dpdv)) return;
    vec3 n = h->ng;
    float ndx = v3_dot(n, dx), ndy = v3_dot(n, dy);
    if (ndx == 0.0f || ndy == 0.0f) return;
    float pd = v3_dot(n, h->p);
    vec3 px = v3_madd(ox, dx, (pd - v3_dot(n, ox)) / ndx), py = v3_madd(oy, dy, (pd - v3_dot(n, oy)) / ndy);
    vec3 dpdx = v3_sub(px, h->p), dpdy = v3_sub(py, h->p);
    float a00 = v3_dot(dpdu, dpdu), a01 = v3_dot(dpdu, dpdv), a11 = v3_dot(dpdv, dpdv);
    float inv = 1.0f / (a00 * a11 - a01 * a01);
    if (!isfinite(inv)) inv = 0.0f;
    float b0x = v3_dot(dpdu, dpdx), b1x = v3_dot(dpdv, dpdx), b0y = v3_dot(dpdu, dpdy), b1y = v3_dot(dpdv, dpdy);
    float r[4] = {(a11 * b0x - a01 * b1x) * inv, (a00 * b1x - a01 * b0x) * inv, (a11 * b0y - a01 * b1y) * inv,
                  (a00 * b1y - a01 * b0y) * inv};
    for (int i = 0; i < 4; i++) h->duv[i] = isfinite(r[i]) ? fminf(1e8f, fmaxf(-1e8f, r[i])) : 0.0f;
}
