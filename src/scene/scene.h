/* scene.h — the validated, immutable scene that the pbrt-v4 parser produces and the renderer reads.
 *
 * Everything is in world space (pbrt's "render space" = world) except the geometry of object
 * definitions used by ObjectInstance, which is stored once and placed by pn_instance transforms.
 * Units and conventions follow pbrt-v4: RGB values are linear Rec.709/sRGB primaries; an
 * AreaLightSource's "L" becomes radiance (W/(m^2 sr)) already multiplied by "scale" (and by the
 * "power" normalisation when given); point and spot "I" becomes intensity (W/sr) likewise.
 */
#ifndef PN_SCENE_SCENE_H
#define PN_SCENE_SCENE_H

#include "core/error.h"
#include "core/warn.h"
#include "core/vecmath.h"
#include "penumbra/penumbra.h"

#include <stdbool.h>
#include <stdint.h>

struct pn_image_s; /* io/image.h */

/* ---- textures ---------------------------------------------------------------------------- */

/* A parameter that is either a constant or a texture: texture < 0 means `value` is used. Float
 * parameters use value.x. */
typedef struct pn_texref {
    int texture;
    vec3 value;
} pn_texref;

typedef enum pn_texture_kind {
    PN_TEXTURE_CONSTANT = 0,    /* value */
    PN_TEXTURE_IMAGE = 1,       /* image[] lookup with (s, 1 - t), bilinear, wrap */
    PN_TEXTURE_SCALE = 2,       /* a * b   ("tex" * "scale") */
    PN_TEXTURE_MIX = 3,         /* (1 - amount) * a + amount * b */
    PN_TEXTURE_CHECKERBOARD = 4 /* 2D checkerboard of a ("tex1") and b ("tex2") */
} pn_texture_kind;

typedef enum pn_wrap_mode { PN_WRAP_REPEAT = 0, PN_WRAP_CLAMP = 1, PN_WRAP_BLACK = 2 } pn_wrap_mode;

/* An image texture's "filter" (pbrt-v4 MIPMap; scene/mipmap.c): all pick a pyramid level from the
 * footprint; EWA is read as trilinear. */
typedef enum pn_texture_filter {
    PN_TEXTURE_FILTER_BILINEAR = 0, /* pbrt-v4's default */
    PN_TEXTURE_FILTER_POINT = 1,
    PN_TEXTURE_FILTER_TRILINEAR = 2
} pn_texture_filter;

/* One level of a texture pyramid: linear RGB floats, top row first. */
typedef struct pn_mip_level {
    int width, height;
    float *rgb;
} pn_mip_level;

/* A texture pyramid (scene/mipmap.c): level 0 is the image, resized up to powers of two. */
typedef struct pn_mipmap {
    int image; /* the pn_texture_image it was built from */
    pn_wrap_mode wrap;
    int levels;
    pn_mip_level *level;
} pn_mipmap;

typedef struct pn_texture {
    pn_texture_kind kind;
    bool is_float;            /* "float" texture (single channel, stored in .x of results) */
    vec3 value;               /* CONSTANT */
    int image;                /* IMAGE: index into pn_scene_s.images */
    float su, sv, du, dv;     /* uv mapping: s = su*u + du, t = sv*v + dv */
    float scale;              /* IMAGE: multiplies the looked-up value (pbrt "scale") */
    bool invert;              /* IMAGE: 1 - value */
    bool float_first_channel; /* IMAGE, float: the first channel of an RGB image instead of the
                                 channel average (pbrt-v4's point / EWA filters; texture.c) */
    pn_wrap_mode wrap;
    pn_texture_filter filter; /* IMAGE */
    int mipmap;               /* IMAGE: index into pn_scene_s.mipmaps */
    pn_texref a, b, amount;   /* SCALE: a*b; MIX: a, b, amount; CHECKERBOARD: a=tex1, b=tex2 */
    char *name;
} pn_texture;

/* A decoded texture image: linear RGB floats, top row first (8-bit sources decoded per the
 * texture's "encoding", sRGB by default). */
typedef struct pn_texture_image {
    int width, height;
    float *rgb; /* 3 * width * height */
    char *path;
} pn_texture_image;

/* ---- materials --------------------------------------------------------------------------- */

/* penumbra's reflection models (ARCHITECTURE.md, "Materials from pbrt-v4 scenes"):
 *  LAMBERT_BLINN: f = kd/pi + ks (n+2)/(2 pi) cos^n(beta)   (normalised Blinn–Phong lobe,
 *                 IlluminationCut eq. 1); ks = 0 means pure Lambert.
 *  MIRROR: perfect specular reflection with RGB reflectance `specular` (eye rays follow it).
 *  DIELECTRIC: perfect specular reflection + refraction with index `eta` for eye rays; opaque to
 *              shadow rays. `specular` tints both.
 *  INTERFACE: invisible (pbrt's "interface"); eye and shadow rays pass through.
 *  MIX: pbrt-v4's mix, resolved per hit (shade/bsdf.c): materials mix[1] with probability
 *       `mix_amount` at the hit's (u, v), else mix[0], chosen by a hash of the hit. Never seen
 *       by the shading code, which gets the chosen material's model. */
typedef enum pn_material_kind {
    PN_MATERIAL_LAMBERT_BLINN = 0,
    PN_MATERIAL_MIRROR = 1,
    PN_MATERIAL_DIELECTRIC = 2,
    PN_MATERIAL_INTERFACE = 3,
    PN_MATERIAL_MIX = 4
} pn_material_kind;

typedef struct pn_material {
    pn_material_kind kind;
    pn_texref kd;   /* diffuse reflectance (RGB) */
    pn_texref ks;   /* glossy coefficient k_spec (RGB), 0 = none */
    float exponent; /* Blinn–Phong exponent n */
    vec3 specular;  /* MIRROR / DIELECTRIC tint */
    float eta;      /* DIELECTRIC */
    bool thin;      /* DIELECTRIC: a thin pane (thindielectric, or dielectric "bool thin" true): shadow rays
                       pass it attenuated by its slab transmittance (accel/glass.c) */
    /* Lambert under a smooth dielectric coating (pbrt-v4 coateddiffuse): the diffuse reflectance
     * seen from outside is kd * coat_transmission / (1 - kd * coat_internal) per channel, with
     * coat_transmission = (1 - Fbar)^2 / eta^2 (in through the coating and out again, radiance
     * compressed by eta^2) and coat_internal = 1 - (1 - Fbar) / eta^2 (the part of the diffuse
     * light inside that the coating reflects back down); Fbar is the coating's cosine-weighted
     * hemispherical Fresnel reflectance. */
    bool coated;
    float coat_transmission, coat_internal;
    int mix[2];           /* MIX: the two materials (indices, defined before this one) */
    pn_texref mix_amount; /* MIX: probability of mix[1] (channel average of the value) */
    char *name;           /* pbrt name ("" for anonymous Material directives) */
    char *description;    /* one line: "NAME: pbrt TYPE -> penumbra model (parameters)" */
    /* Conductors whose eta and k are named spectra with tables (spectral/metals.h): the tables,
     * from which spectral mode evaluates F0 (ks, or specular when a mirror) at each wavelength;
     * NULL otherwise (RGB mode always uses the RGB F0 in ks / specular). */
    const struct pn_metal_table *eta_table, *k_table;
    /* The same for eta or k given as a tabulated spectrum (numbers or an .spd file; owned by the
     * scene, scene->spds), where the named table above is NULL. */
    const struct pn_spd *eta_spd, *k_spd;
    /* diffuse and coateddiffuse: "reflectance" given as a tabulated spectrum (numbers or an .spd
     * file; owned by the scene), which spectral mode evaluates at each wavelength instead of
     * upsampling kd's RGB; NULL otherwise (RGB, textures, named spectra). */
    const struct pn_spd *kd_spd;
} pn_material;

/* ---- geometry ---------------------------------------------------------------------------- */

/* Emission of an area light attached to a shape (AreaLightSource "diffuse"). */
typedef struct pn_emission {
    vec3 radiance; /* L * scale (* power normalisation) */
    bool two_sided;
    /* "power" normalised per pbrt-v4 shape inside a mesh: 0 = radiance is final; 1 = each
     * triangle is a shape, 2 = each pair of triangles (2i, 2i + 1) is one (a bilinear patch).
     * The radiance of a triangle is then radiance / (area of its shape); pn_emission_area_scale
     * (lights/lights.h) computes the factor. */
    int per_shape;
    /* "blackbody" L: the temperature (K) and pn_blackbody_unit_scale of it, which spectral mode
     * emits instead of upsampling radiance (spectral/transport.h); 0 for other emissions. */
    float kelvin, kelvin_scale;
    /* A tabulated "spectrum" L (numbers, .spd, stdillum-D65/-A): the spectrum spectral mode emits
     * (pn_swl_tabulated), owned by the scene; NULL otherwise. */
    const struct pn_spd *spd;
} pn_emission;

/* A triangle mesh. Positions/normals are in world space, or in the object's space for meshes of
 * an object definition (object >= 0). Normals are unit length. */
typedef struct pn_mesh {
    uint32_t vertex_count, triangle_count;
    float *positions;  /* 3 * vertex_count */
    float *normals;    /* 3 * vertex_count or NULL */
    float *uvs;        /* 2 * vertex_count or NULL */
    uint32_t *indices; /* 3 * triangle_count */
    int material;      /* index into materials */
    pn_texref alpha;   /* alpha cut-out: texture >= 0, or value.x < 1 to cut everything */
    int emission;      /* index into emissions, or -1 */
    /* pbrt: ReverseOrientation XOR the transform swaps handedness. The geometric normal of a
     * triangle is normalize(cross(p1 - p0, p2 - p0)), negated when this is true, then (if the
     * mesh has normals) flipped to the side of the interpolated shading normal. One-sided
     * emitters emit on the side of that geometric normal. */
    bool flip_normals;
    int object;   /* -1: world geometry; >= 0: belongs to objects[object] */
    int disk;     /* >= 0: this mesh tessellates disks[disk] (for analytic disk lights) */
    char *source; /* "file:line:column" of the Shape directive, for messages */
} pn_mesh;

/* An analytic sphere (pbrt "sphere" with full zmin/zmax/phimax). A non-uniform scale in its
 * transform is approximated by the cube root of the determinant (with a warning). */
typedef struct pn_sphere {
    vec3 center;
    float radius;
    int material;
    int emission;      /* -1 or index into emissions */
    bool flip_normals; /* normals point inward */
    int object;
    char *source; /* "file:line:column" of the Shape directive, for messages */
    /* The object frame's x, y, z axes in the space of `center` (unit): (u, v) are pbrt-v4's,
     * taken in object space, so they turn with the sphere's transform. */
    vec3 axis[3];
} pn_sphere;

/* An analytic disk as a light source; its geometry is also tessellated into a pn_mesh. */
typedef struct pn_disk {
    vec3 center, normal; /* normal already flipped per ReverseOrientation/handedness */
    float radius;
    float inner_radius; /* pbrt "innerradius" (0 = full disk) */
    int mesh;           /* the tessellated mesh */
} pn_disk;

typedef struct pn_object {
    char *name;
    int first_mesh, mesh_count; /* meshes[first_mesh .. +mesh_count) */
    int first_sphere, sphere_count;
} pn_object;

typedef struct pn_instance {
    int object;
    mat4 world_from_object;
} pn_instance;

/* ---- lights (LightSource directives; area lights come from emissive shapes) --------------- */

typedef enum pn_light_def_kind {
    PN_LIGHTDEF_POINT = 0,
    PN_LIGHTDEF_SPOT = 1,
    PN_LIGHTDEF_DISTANT = 2,
    PN_LIGHTDEF_INFINITE = 3,
    PN_LIGHTDEF_GONIOMETRIC = 4,
    PN_LIGHTDEF_PROJECTION = 5
} pn_light_def_kind;

typedef struct pn_light_def {
    pn_light_def_kind kind;
    vec3 position;                            /* POINT, SPOT, GONIOMETRIC: world position */
    vec3 direction;                           /* SPOT: unit axis of the cone (from -> to); DISTANT: unit direction
                           TOWARDS the light (from - to, normalised) */
    vec3 intensity;                           /* POINT/SPOT/GONIOMETRIC: I * scale (W/sr); DISTANT: L * scale
                           (irradiance on a surface facing it); INFINITE: constant L * scale
                           when image < 0, else the scale in .x,.y,.z */
    float cos_falloff_start, cos_total_width; /* SPOT: pbrt's smoothstep falloff */
    int image;                                /* INFINITE or GONIOMETRIC: index into images, or -1 */
    bool equal_area;                          /* INFINITE image: pbrt-v4 equal-area octahedral (square image);
                           false: equirectangular (latitude-longitude) */
    mat4 world_from_light;                    /* INFINITE / GONIOMETRIC orientation */
    mat4 light_from_world;
    char *source;               /* "file:line" */
    float fov_deg;              /* PROJECTION: the frustum's angle across the image's shorter side */
    int photometry;             /* GONIOMETRIC from an IES / EULUMDAT file: index into photometries, or -1 */
    double photometry_scale;    /* that file's candela times this is what the light emits */
    float kelvin, kelvin_scale; /* "blackbody" I or L (point, spot, goniometric, distant): as pn_emission's */
    const struct pn_spd *spd;   /* a tabulated "spectrum" I or L (the same lights): as pn_emission's */
} pn_light_def;

/* ---- camera and film --------------------------------------------------------------------- */

typedef enum pn_filter_kind {
    PN_FILTER_BOX = 0,
    PN_FILTER_TRIANGLE = 1,
    PN_FILTER_GAUSSIAN = 2,
    PN_FILTER_MITCHELL = 3
} pn_filter_kind;

/* pbrt-v4's camera models (cameras.cpp). Zero is the perspective camera. */
typedef enum pn_camera_projection {
    PN_PROJECTION_PERSPECTIVE = 0,
    PN_PROJECTION_ORTHOGRAPHIC = 1,   /* rays along +z from the screen window at z = 0 */
    PN_PROJECTION_EQUAL_AREA = 2,     /* "spherical", mapping "equalarea" (Clarberg octahedral) */
    PN_PROJECTION_EQUIRECTANGULAR = 3 /* "spherical", mapping "equirectangular" */
} pn_camera_projection;

typedef struct pn_camera_def {
    mat4 camera_from_world, world_from_camera;
    pn_camera_projection projection;
    float fov_deg;          /* of the shorter image axis, pbrt's "fov" (default 90) */
    float screen_window[4]; /* xmin, xmax, ymin, ymax (default from the aspect ratio) */
    float lens_radius, focal_distance;
    int width, height; /* Film resolution (default 1280 x 720) */
    float crop[4];     /* x0, x1, y0, y1 (default 0 1 0 1) */
    pn_filter_kind filter;
    float filter_radius[2];
    float gaussian_sigma;
    float mitchell_b, mitchell_c;
    /* Film pixelbounds (pbrt: an integer window [x0,x1) x [y0,y1) of the full resolution):
     * when given, crop[] holds the same window as fractions and the renderer uses these
     * integers whenever it renders the scene's own crop at the scene's own resolution. */
    bool pixel_bounds_given;
    int pixel_bounds[4]; /* x0, x1, y0, y1 */
    /* The film's response, applied to the finished image in one place (pn_camera_film_apply):
     * RGB -> XYZ, times imaging_ratio, clamped so that no XYZ component exceeds
     * max_component_value (0 = no clamp), white-balanced from the CIE daylight (or, below 4000 K,
     * blackbody) white of white_balance_k to D65 with the Bradford (von Kries) transform
     * (0 = none), -> RGB. pbrt-v4: the "cie1931" PixelSensor and RGBFilm. */
    float imaging_ratio; /* (shutterclose - shutteropen) * iso / 100; 0 reads as 1 */
    float max_component_value;
    float white_balance_k;
    float shutter_open, shutter_close; /* Camera parameters, kept for the imaging ratio */
    float iso;                         /* Film parameter */
    int pixel_samples;                 /* Sampler "pixelsamples", reported only */
    char *film_filename;
    char *integrator_name; /* Integrator, reported only */
    int max_depth;         /* Integrator "maxdepth" (pbrt's default 5 when absent) */
    bool max_depth_given;  /* the scene gave "maxdepth": the VPL integrators' default light-path
                               depth becomes max_depth - 1 bounces (pn_scene_vpl_depth) */
} pn_camera_def;

/* ---- the scene --------------------------------------------------------------------------- */

struct pn_accel;  /* accel/accel.h */
struct pn_lights; /* lights/lights.h */

struct pn_scene_s {
    pn_context ctx; /* for logging only; not owned */
    char *path;

    pn_camera_def camera;

    pn_mesh *meshes;
    int mesh_count;
    pn_sphere *spheres;
    int sphere_count;
    pn_disk *disks;
    int disk_count;
    pn_object *objects;
    int object_count;
    pn_instance *instances;
    int instance_count;

    pn_material *materials;
    int material_count;
    pn_texture *textures;
    int texture_count;
    pn_texture_image *images;
    int image_count;
    pn_mipmap *mipmaps; /* pyramids of the images image textures read (per image and wrap mode) */
    int mipmap_count;
    pn_emission *emissions;
    int emission_count;
    pn_light_def *light_defs;
    int light_def_count;
    struct pn_photometry **photometries; /* measured luminaires, one per distinct file (scene/photometry.h) */
    int photometry_count;
    struct pn_spd **spds; /* tabulated emission spectra for spectral mode (pn_params_light_spectrum) */
    int spd_count;

    pn_warning_list warnings; /* "file:line:column: message"; parser and light builder (core/warn.h) */

    vec3 bounds_min, bounds_max; /* of world geometry and instances */
    double parse_seconds, bvh_seconds;

    struct pn_accel *accel;   /* built after parsing */
    struct pn_lights *lights; /* built after parsing */
};

/* Parses the file into a new scene (geometry, materials, lights, camera; no BVH, no light
 * records). On failure returns the status with err = "file:line:column: message" and *out NULL.
 * Warnings are stored in the scene and also sent to ctx's log. */
pn_status pn_scene_parse(pn_context ctx, const char *path, struct pn_scene_s **out, pn_err *err);

/* Frees everything parse allocated (accel and lights are freed by pn_scene_free). */
void pn_scene_parse_free(struct pn_scene_s *scene);

/* The parser's shorthand for pn_warn(scene->ctx, &scene->warnings, ...): adds a warning to the
 * scene (copies the text) and logs it. */
void pn_scene_warn(struct pn_scene_s *scene, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* The VPL integrators' default light-path depth (bounces that may leave a VPL) for this scene:
 * pbrt's maxdepth counts scattering events of a whole path, and a VPL left after k bounces
 * lights the receiving point over a path of k + 1 of them, so maxdepth D means D - 1 bounces.
 * Without an Integrator "maxdepth" in the scene this is `fallback` (penumbra's own default). */
uint32_t pn_scene_vpl_depth(const struct pn_scene_s *scene, uint32_t fallback);

/* Texture evaluation at surface coordinates (u, v); returns RGB (float textures: all three
 * channels equal). Implemented in scene/texture.c. Image textures are read from their pyramid's
 * finest level (a zero footprint). */
vec3 pn_texture_eval(const struct pn_scene_s *scene, pn_texref ref, float u, float v);

/* The same with the screen-space footprint of the lookup, duv = (du/dx, dv/dx, du/dy, dv/dy)
 * (pn_hit's uv derivatives; NULL: zero), which chooses the pyramid level of image textures. */
vec3 pn_texture_eval_footprint(const struct pn_scene_s *scene, pn_texref ref, float u, float v, const float duv[4]);

/* ---- texture pyramids (scene/mipmap.c) ---- */
/* Builds the pyramid of an rgb image (w x h, linear) for a wrap mode; free with pn_mipmap_free. */
pn_status pn_mipmap_build(const float *rgb, int width, int height, pn_wrap_mode wrap, pn_mipmap *out, pn_err *err);
void pn_mipmap_free(pn_mipmap *m);
/* The filtered value at (s, t) (t down from the top row) with the footprint
 * dst = (ds/dx, dt/dx, ds/dy, dt/dy), as pbrt-v4's MIPMap::Filter. */
vec3 pn_mipmap_lookup(const pn_mipmap *m, pn_texture_filter filter, float s, float t, const float dst[4]);
/* Bilinear lookup in one level, texel centres at (i + 0.5) / size. */
vec3 pn_mip_level_bilerp(const pn_mip_level *lv, float s, float t, pn_wrap_mode wrap);

#endif
