/* accel.h — ray queries against the scene through Embree (the only module that includes Embree). */
#ifndef PN_ACCEL_ACCEL_H
#define PN_ACCEL_ACCEL_H

#include "core/error.h"
#include "core/vecmath.h"

#include <stdbool.h>

struct pn_scene_s;
typedef struct pn_accel pn_accel;

/* What an eye ray found: the surface point with its frame and what is attached to it. */
typedef struct pn_hit {
    float t;
    vec3 p;
    vec3 ng;    /* unit geometric normal, oriented by pbrt's rules (not towards the ray) */
    vec3 ns;    /* unit shading normal (interpolated when the mesh has normals; else ng) */
    float u, v; /* texture coordinates */
    int material;
    int emission;  /* index into scene emissions, or -1 */
    int mesh;      /* index into scene meshes, or -1 for a sphere */
    int sphere;    /* index into scene spheres, or -1 */
    unsigned prim; /* triangle index within the mesh */
    int instance;  /* -1 for world geometry */
    /* Screen-space derivatives of (u, v): du/dx, dv/dx, du/dy, dv/dy (pn_hit_uv_footprint);
     * zero (the finest texture level) unless the eye path set them. */
    float duv[4];
} pn_hit;

/* Builds the BVH over the scene's meshes, spheres and instances. */
pn_status pn_accel_build(struct pn_scene_s *scene, pn_accel **out, pn_err *err);
void pn_accel_free(pn_accel *accel);

/* Closest hit along o + t d for t in (tmin, tmax); d need not be unit length (t is in units of
 * |d|). Returns false on a miss. */
bool pn_accel_intersect(const pn_accel *accel, vec3 o, vec3 d, float tmin, float tmax, pn_hit *hit);
/* The same for a shadow ray's surfaces: thin glass panes (see pn_accel_transmittance) are passed,
 * so the hit is the first opaque blocker, emitters included. */
bool pn_accel_intersect_opaque(const pn_accel *accel, vec3 o, vec3 d, float tmin, float tmax, pn_hit *hit);

/* pbrt-v4's dp/du and dp/dv of a triangle hit (world space), from its vertices' (u, v) (the
 * default (0,0), (1,0), (1,1) without them); an arbitrary orthonormal pair in the triangle's
 * plane when the (u, v) are degenerate (Triangle::InteractionFromIntersection). False for
 * spheres. */
bool pn_accel_hit_uv_partials(const pn_accel *accel, const pn_hit *hit, vec3 *dpdu, vec3 *dpdv);

/* Sets hit->duv from ray differentials (origins ox, oy, directions dx, dy) as pbrt-v4's
 * SurfaceInteraction::ComputeDifferentials: the offset rays meet the hit's tangent plane
 * (geometric normal) at p + dp/dx, p + dp/dy, and (du, dv) solve dp = du dp/du + dv dp/dv in the
 * least-squares sense; non-finite values become 0, the rest is clamped to [-1e8, 1e8]. */
void pn_hit_uv_footprint(const pn_accel *accel, pn_hit *hit, vec3 ox, vec3 dx, vec3 oy, vec3 dy);

/* True if anything blocks o + t d for t in (tmin, tmax). */
bool pn_accel_occluded(const pn_accel *accel, vec3 o, vec3 d, float tmin, float tmax);

/* occluded[i] = pn_accel_occluded(accel, o[i], d[i], tmin[i], tmax[i]) for i < count, the rays
 * traced together as Embree packets of up to 16 (for coherent rays: e.g. from nearby points to
 * one light). Rays through a triangle edge may be answered differently (Embree's packet and
 * single-ray triangle tests differ there; see accel.c). */
void pn_accel_occluded_packet(const pn_accel *accel, int count, const vec3 *o, const vec3 *d, const float *tmin,
                              const float *tmax, bool *occluded);

/* Thin glass (a thindielectric, or a dielectric marked thin): plain occlusion queries above treat
 * panes as opaque, as pbrt-v4 does; these pass them. The transmittance of o + t d for t in
 * (tmin, tmax): 0 when an opaque surface blocks it, else the product over the thin panes crossed
 * of their slab transmittance pn_thin_glass_transmittance (core/optics.h) at the crossing's
 * angle (at most PN_ACCEL_MAX_PANES panes are counted). Exactly 1 when the scene has no pane. */
#define PN_ACCEL_MAX_PANES 64
float pn_accel_transmittance(const pn_accel *accel, vec3 o, vec3 d, float tmin, float tmax);
/* transmittance[i] = pn_accel_transmittance(...) for i < count, the opaque test traced as packets
 * (as pn_accel_occluded_packet). */
void pn_accel_transmittance_packet(const pn_accel *accel, int count, const vec3 *o, const vec3 *d, const float *tmin,
                                   const float *tmax, float *transmittance);
/* Whether the scene has a thin glass pane. */
bool pn_accel_has_thin_glass(const pn_accel *accel);

/* A distance scale for ray-origin offsets: 1e-4 of the scene's bounding-box diagonal at most, and
 * relative to the coordinates' magnitude. */
float pn_accel_ray_epsilon(const pn_accel *accel, vec3 p);

#endif
