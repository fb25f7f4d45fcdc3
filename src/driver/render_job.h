/* render_job.h — everything an integrator needs to know about one render, resolved once. */
#ifndef PN_DRIVER_RENDER_JOB_H
#define PN_DRIVER_RENDER_JOB_H

#include "accel/accel.h"
#include "driver/camera.h"
#include "lights/lights.h"
#include "scene/scene.h"

#include <stdatomic.h>

typedef struct pn_render_job {
    const struct pn_scene_s *scene;
    const pn_accel *accel;
    const pn_lights *lights;
    pn_camera camera;
    /* Settings with defaults applied. */
    uint32_t spp;                 /* 0: adaptive */
    double threshold;
    uint32_t shadow_rays;         /* per eye ray */
    uint32_t max_shadow_rays;     /* per pixel */
    uint32_t min_shadow_rays_black;
    uint32_t min_eye_rays;
    uint32_t max_specular_depth;
    uint64_t seed;
    uint32_t aovs;
    /* ias */
    float cluster_solid_angle;
    uint32_t aa_rays, env_regions, max_passes;
    uint32_t block_size; /* pixels per side of the tiled driver's blocks (ias: its blocks) */
    /* reference */
    pn_light_sampler light_sampler; /* IRRADIANCE or BVH, never DEFAULT */
    /* VPL integrators (issue 5) */
    uint32_t vpls, vpl_max_depth, max_cut;
    float vpl_clamp_fraction, error_bound;
    bool visibility_sampling;
    bool vpl_direct_only; /* the lights themselves as VPLs, no bounces (direct light only) */
    /* contour / contour-mc (Vedel 1993; Kok & Jansen 1992) */
    uint32_t contour_grid, contour_steps, contour_span, contour_flags;
    double contour_mc_threshold;
    uint32_t contour_mc_max_rays;
    void *integrator_data; /* what the integrator's prepare() built for this render */
    atomic_int *cancel;
    struct pn_progress *progress; /* driver/progress.h: the render's progress path (may be NULL) */
} pn_render_job;

/* The result of following an eye ray through perfect specular interactions to the first
 * non-specular surface. */
typedef struct pn_eye_path {
    vec3 emitted;     /* radiance collected along the way (emitters, environment), weighted */
    bool has_point;   /* ended at a surface with a non-specular lobe */
    vec3 throughput;  /* product of specular tints up to the point */
    pn_hit hit;
    vec3 wo;          /* unit direction from the point back along the path */
    uint32_t rays;    /* intersect calls made (1 + specular bounces) */
    float first_depth;
    vec3 first_normal;
    vec3 first_albedo;
} pn_eye_path;

/* Traces the camera ray o + t d through mirrors, dielectrics and interfaces. u_specular drives
 * the first reflect/refract choice; deeper choices use a hash of (seed, u_specular, depth). */
void pn_trace_eye_path(const pn_render_job *job, vec3 o, vec3 d, float u_specular, pn_eye_path *path);

/* Eye sample i of full-image pixel (px, py) in the per-pixel convention of the `reference`
 * integrator: one scrambled Sobol sequence per pixel (the scramble a hash of the seed and the
 * pixel), dimensions 0-1 the position under the pixel filter (its weight in *fw), 2-3 the lens,
 * 4 the specular choice. The camera ray goes to *o, *d; pn_trace_eye_path takes *u_specular. */
uint32_t pn_pixel_scramble(const pn_render_job *job, int px, int py);
void pn_pixel_eye_sample(const pn_render_job *job, int px, int py, uint32_t scramble, uint32_t i, vec3 *o, vec3 *d,
                         float *fw, float *u_specular);

#endif
