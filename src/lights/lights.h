/* lights.h — every light of a scene behind one record: point, spot, distant, triangle, rectangle,
 * disk, sphere and environment lights; sampling, evaluation, and the unoccluded-irradiance
 * estimate that the reference integrator's light PDF uses (IAS paper §5.1). */
#ifndef PN_LIGHTS_LIGHTS_H
#define PN_LIGHTS_LIGHTS_H

#include "core/error.h"
#include "core/sampling.h"
#include "core/vecmath.h"

#include <stdbool.h>
#include <stdint.h>

struct pn_scene_s;
struct pn_distribution2d;

typedef enum pn_light_kind {
    PN_LIGHT_POINT = 0,
    PN_LIGHT_SPOT = 1,
    PN_LIGHT_DISTANT = 2,
    PN_LIGHT_TRIANGLE = 3,
    PN_LIGHT_RECTANGLE = 4,
    PN_LIGHT_DISK = 5,
    PN_LIGHT_SPHERE = 6,
    PN_LIGHT_ENVIRONMENT = 7,
    PN_LIGHT_GONIOMETRIC = 8,
    PN_LIGHT_PROJECTION = 9,
    PN_LIGHT_KIND_COUNT = 10
} pn_light_kind;

typedef struct pn_light {
    pn_light_kind kind;
    vec3 p;       /* POINT/SPOT: position; TRIANGLE/RECTANGLE: corner p0; DISK/SPHERE: centre */
    vec3 e1, e2;  /* TRIANGLE: p1 - p0, p2 - p0; RECTANGLE: the two edges from p0 */
    vec3 n;       /* unit emitting normal (TRIANGLE/RECTANGLE/DISK), SPOT axis, DISTANT
                        direction towards the light */
    float radius; /* DISK, SPHERE */
    float area;   /* m^2 (TRIANGLE/RECTANGLE/DISK/SPHERE) */
    vec3 emit;    /* radiance (area, distant: irradiance, env: scale), intensity (point/spot) */
    float cos_falloff_start, cos_total_width; /* SPOT */
    bool two_sided;
    int env;        /* ENVIRONMENT: index into pn_lights.envs; GONIOMETRIC: into .gonios;
                        PROJECTION: into .projections (whose axis is n and whose frustum lies
                        within cos_total_width of it) */
    int mesh, prim; /* area lights from meshes: source triangle(s), for `info` and tests */
    float power;    /* PROJECTION: luminous power, luminance(emit * phi) (pn_projection) */
    /* A "blackbody" emission: its temperature (K) and pn_blackbody_unit_scale, which spectral mode
     * emits (pn_light_radiance_spectral) instead of upsampling emit; 0 otherwise. */
    float kelvin, kelvin_scale;
    /* A tabulated "spectrum" emission (scene-owned, spectral/transport.h pn_spd), which spectral
     * mode emits (pn_swl_tabulated) instead of upsampling emit; NULL otherwise. */
    const struct pn_spd *spd;
} pn_light;

/* An environment map prepared for lookup and importance sampling by luminance. */
typedef struct pn_env {
    int width, height;
    const float *rgb; /* owned by the scene's image table, or `constant` when NULL */
    vec3 constant;
    vec3 scale;
    bool equal_area;
    mat4 world_from_light, light_from_world;
    struct pn_distribution2d *dist; /* over pixels, NULL for constant maps */
    float average_luminance;
    bool has_sh;            /* irradiance_sh holds the map's irradiance in 9 harmonics */
    float irradiance_sh[9]; /* light space; coefficients already multiplied by A_l */
} pn_env;

/* The lights again as plain arrays, for pn_lights_irradiance_all (light_pdf.c). */
typedef struct pn_light_soa {
    float *cx, *cy, *cz; /* centre: position, centroid, or disk / sphere centre */
    float *nx, *ny, *nz; /* emitting normal of planar lights, else 0 */
    float *r2;           /* squared bounding radius (0 for points) */
    float *power;        /* luminance of the far-field source term (see light_pdf.c) */
    float *far2;         /* squared distance beyond which the far field is used */
    float *pointlike;    /* 1 for points and spheres, else 0 */
    float *two_sided;    /* 1 for two-sided planar lights, else 0 */
    float *one_sided;    /* 1 for one-sided planar lights, else 0 */
    int *only_exact;     /* 1 where only pn_light_irradiance_estimate applies (spot, ...) */
} pn_light_soa;

/* The angular distribution of a goniometric light (pbrt-v4): a square image in the equal-area
 * octahedral mapping, looked up (nearest texel, mean of the channels) in the light's frame with
 * y and z swapped, as goniometric diagrams have +y up. NULL mono: isotropic. */
typedef struct pn_gonio {
    int width, height;
    float *mono;
    float peak; /* max(1, largest mono value): the VPL of the light carries emit * peak and the
                   factor relative to it (<= 1), so that the cuts' bounds hold (lights/vpl.c) */
    mat4 light_from_world;
    /* A measured luminaire (IES / EULUMDAT, lights/photometric.c) instead of an image: the
     * factor is candela / peak candela (<= 1; emit carries the peak), looked up in the light's
     * own frame (nadir -z, C = 0 along +x; no y-z swap). NULL for image lights. */
    const struct pn_photometry *photo;
    double inv_peak_cd;
    mat4 world_from_light;
    float abs_det;                  /* |det| of world_from_light's 3x3 (solid-angle Jacobian) */
    struct pn_distribution2d *dist; /* directions by intensity over (phi, gamma) cells */
    bool owns_dist;                 /* false when it is shared with an earlier light of the same file */
    vec3 nadir;                     /* world direction of gamma = 0, unit */
    float cos_max_gamma;            /* cosine of the largest lit gamma (type C), -1 when all */
    bool rigid;                     /* world_from_light preserves angles (the cone bound holds) */
} pn_gonio;

/* A projection light (pbrt-v4 "projection", lights/projection.c): a point that shines an image
 * through a perspective frustum, as a slide projector. A world direction w leaving the light is
 * taken to light space (w_l = light_from_world w, with pbrt's y flip included), projected to the
 * screen point (w_l.x, w_l.y) / (w_l.z tan(fov / 2)), and inside the screen window
 * [-sx, sx] x [-sy, sy] (the shorter image side spans [-1, 1]) reads the nearest pixel; the
 * intensity is emit * rgb there, zero outside the frustum. */
typedef struct pn_projection {
    int width, height;
    const float *rgb;                        /* width * height RGB, top row first; owned by the scene's image table */
    mat4 world_from_light, light_from_world; /* y already flipped as pbrt-v4 does */
    float abs_det;                           /* |det| of world_from_light's 3x3 (solid-angle Jacobian) */
    float tan_half_fov, sx, sy;
    float plane_area;               /* A = (2 sx tan)(2 sy tan): the window's area on the plane z = 1 */
    vec3 phi;                       /* power per unit emit: A * mean(rgb cos^3), per channel */
    float peak;                     /* largest channel of any pixel (>= every rgb value) */
    float mean_max;                 /* mean over pixels of the largest channel (pbrt-v4's Bounds) */
    struct pn_distribution2d *dist; /* pixels weighted by mean(rgb) cos^3: directions by intensity */
} pn_projection;

typedef struct pn_lights {
    pn_light *lights;
    int count;
    pn_env *envs;
    int env_count;
    pn_gonio *gonios;
    int gonio_count;
    int count_by_kind[PN_LIGHT_KIND_COUNT];
    float scene_radius;
    vec3 scene_center;
    pn_light_soa soa;
    pn_projection *projections;
    int projection_count;
} pn_lights;

/* Builds the light records: LightSource definitions, and emissive shapes (a mesh's triangle pairs
 * that form planar rectangles become RECTANGLE lights, other triangles TRIANGLE lights, disks
 * DISK lights, spheres SPHERE lights). Zero-area and zero-power emitters, and emitters whose
 * material is "interface" (pbrt-v4 creates no area light for them), are dropped with a warning.
 * With "power" per pbrt-v4 shape (pn_emission.per_shape) each triangle gets its own radiance. */
pn_status pn_lights_build(struct pn_scene_s *scene, pn_lights **out, pn_err *err);
void pn_lights_free(pn_lights *lights);

/* A sample of the light arriving at a receiving point. */
typedef struct pn_light_sample {
    vec3 wi;       /* unit direction from the receiver towards the light */
    float dist;    /* distance to the sampled point (INFINITY for distant/environment) */
    vec3 radiance; /* incident radiance (delta lights: intensity / d^2, or irradiance) */
    float pdf;     /* solid-angle density; for delta lights 1 */
    bool delta;
} pn_light_sample;

/* Samples light `l` as seen from point p with normal n; u in [0,1)^2. Returns false when the
 * sample carries nothing (facing away, outside the spot cone, zero pdf). */
bool pn_light_sample_point(const pn_lights *lights, const pn_light *l, vec3 p, float u1, float u2, pn_light_sample *s);

/* What sampling a rectangle light from one receiver sets up (the spherical rectangle), kept
 * between calls for the same light and point. Zero-initialise before the first use. */
typedef struct pn_light_sample_cache {
    const pn_light *light;
    vec3 p;
    bool spherical;
    pn_spherical_rectangle sr;
} pn_light_sample_cache;

/* pn_light_sample_point with a cache (may be NULL); the results are identical. */
bool pn_light_sample_point_cached(const pn_lights *lights, const pn_light *l, vec3 p, float u1, float u2,
                                  pn_light_sample_cache *cache, pn_light_sample *s);
/* The solid-angle density with which pn_light_sample_point(l, p) gives direction wi whose ray
 * reaches l's surface at distance dist (triangle, rectangle, disk and sphere lights; 0 for the
 * others and for directions sampling would not return, as from behind a one-sided light). */
float pn_light_pdf_direction(const pn_light *l, vec3 p, vec3 wi, float dist);

/* Emitted radiance of an area light toward direction w (unit, from the light's surface point to
 * the viewer), for eye rays that hit an emitter. */
vec3 pn_emission_radiance(const struct pn_scene_s *scene, int emission, vec3 ng, vec3 w);

/* Emitted radiance at an eye-ray hit towards w (unit, from the surface to the viewer): as
 * pn_emission_radiance, with "power" normalised per pbrt-v4 shape when the emission says so. */
struct pn_hit;
vec3 pn_hit_emission(const struct pn_scene_s *scene, const struct pn_hit *hit, vec3 w);
/* pn_hit_emission at the wavelengths wl in spectral mode (NULL: RGB): the emission's RGB as an
 * illuminant spectrum (spectral/transport.h). */
struct pn_swl;
/* A light sample's radiance (or a value of light l times a positive factor, linear sRGB) at the
 * wavelengths wl (NULL: rgb itself): as an illuminant spectrum (spectral/transport.h). */
vec3 pn_light_radiance_spectral(const pn_lights *lights, const pn_light *l, vec3 rgb, const struct pn_swl *wl);
vec3 pn_hit_emission_spectral(const struct pn_scene_s *scene, const struct pn_hit *hit, vec3 w,
                              const struct pn_swl *wl);

/* The factor applied to a mesh emission's radiance for triangle t: 1 / (area of its pbrt-v4
 * shape) when "power" is normalised per shape (pn_emission.per_shape), else 1. */
struct pn_mesh;
struct pn_emission;
float pn_emission_area_scale(const struct pn_mesh *m, const struct pn_emission *e, uint32_t t);

/* The goniometric factor of light l towards world direction w (unit, from the light outwards). */
float pn_gonio_factor(const pn_lights *lights, const pn_light *l, vec3 w);

struct pn_light_def;
/* Measured luminaires (lights/photometric.c). Fills g's photometric fields from the scene's
 * light definition (its photometry, frame and a sampling table shared between lights of the
 * same file: pass the gonios already prepared). */
pn_status pn_gonio_prepare_photometric(const struct pn_scene_s *scene, const struct pn_light_def *d, pn_gonio *g,
                                       const pn_gonio *earlier, int earlier_count, pn_err *err);
/* A direction leaving goniometric light l (photometric) by its intensity; *pdf in world solid
 * angle. False when nothing can be sampled. */
bool pn_gonio_sample_direction(const pn_lights *lights, const pn_light *l, float u1, float u2, vec3 *w, float *pdf);
/* The world solid-angle density of pn_gonio_sample_direction at world unit direction w. */
float pn_gonio_pdf(const pn_lights *lights, const pn_light *l, vec3 w);
/* Luminous power of a photometric light l: luminance(emit) times lumens / peak candela. */
float pn_gonio_photometric_power(const pn_lights *lights, const pn_light *l);

/* Projection lights (lights/projection.c). The rgb factor of light l (PROJECTION) towards world
 * unit direction w from the light outwards: the nearest pixel, clamped at 0; zero outside the
 * frustum. The intensity is l->emit times it. */
vec3 pn_projection_factor(const pn_lights *lights, const pn_light *l, vec3 w);
/* A direction leaving the light, importance-sampled by the image's intensity (pixels weighted by
 * mean(rgb) times the cos^3 of the plane-to-sphere Jacobian, uniform within a pixel on the
 * plane); *pdf is the world solid-angle density. False when nothing can be sampled. */
bool pn_projection_sample_direction(const pn_lights *lights, const pn_light *l, float u1, float u2, vec3 *w,
                                    float *pdf);
/* The solid-angle density of pn_projection_sample_direction at world unit direction w. */
float pn_projection_pdf(const pn_lights *lights, const pn_light *l, vec3 w);
/* Light arriving at p (delta: intensity / d^2), and the exact unoccluded irradiance (luminance)
 * at p with normal n; the PROJECTION cases of pn_light_sample_point and
 * pn_light_irradiance_estimate. */
bool pn_projection_sample_li(const pn_lights *lights, const pn_light *l, vec3 p, pn_light_sample *s);
float pn_projection_irradiance(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n);
/* The luminous power per unit scale of a projection light with image rgb (w x h, top row first)
 * and field of view fov_deg: A * mean over pixels of luminance(rgb) cos^3 (pbrt-v4's "power"
 * normalisation; negative values count as 0). */
double pn_projection_unit_power(const float *rgb, int width, int height, double fov_deg);
/* Fills table entry pr and light record l from the scene's projection light definition (position,
 * intensity = emit, image, orientation with the y flip, fov in degrees). */
struct pn_light_def;
pn_status pn_projection_prepare(const struct pn_scene_s *scene, const struct pn_light_def *d, pn_projection *pr,
                                pn_light *l, pn_err *err);

/* Radiance of all environment lights for an escaping ray with unit direction d. */
vec3 pn_lights_environment_radiance(const pn_lights *lights, vec3 d);
vec3 pn_env_radiance(const pn_env *env, vec3 d);
/* Radiance of an image environment in light-space direction wl (unit), and the map coordinates
 * it was read at. */
vec3 pn_env_lookup(const pn_env *env, vec3 wl, float *u, float *v);

/* The unoccluded irradiance the light would give to a point p with normal n (zero if it is
 * behind the surface, or the point is behind a one-sided light): exact for point, spot, distant
 * and polygon lights (Lambert's contour formula, clipped to the horizon), approximate for disks
 * (a 24-gon), spheres and environment maps. The reference integrator's PDF over lights is
 * proportional to it. */
float pn_light_irradiance_estimate(const pn_lights *lights, const pn_light *l, vec3 p, vec3 n);

/* pn_light_irradiance_estimate for every light at once (out[i] for lights[i]); `exact` is
 * scratch of count ints. Vectorised far field with exact fix-ups (light_pdf.c); returns how many
 * lights needed the exact formula. */
int pn_lights_irradiance_all(const pn_lights *lights, vec3 p, vec3 n, float *out, int *exact);
pn_status pn_lights_build_soa(pn_lights *lights, pn_err *err);
void pn_lights_free_soa(pn_lights *lights);

/* Irradiance at the origin (normal n) from the polygon v[0..count) of uniform unit radiance,
 * clipped to the hemisphere of n (Lambert 1760; the contour-integral form of Vedel's eq. 4). */
float pn_polygon_irradiance(const vec3 *v, int count, vec3 n);

/* pbrt-v4's equal-area octahedral mapping between the unit square and the sphere (Clarberg). */
vec3 pn_equal_area_square_to_sphere(float u, float v);
void pn_equal_area_sphere_to_square(vec3 d, float *u, float *v);

#endif
