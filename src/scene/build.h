/* build.h — turning pbrt-v4 directives into scene records: materials (scene/materials.c),
 * textures (scene/texture.c), spectra (scene/spectrum.c) and light sources (scene/lightdefs.c).
 * The parser (scene/parser.c) calls these with the directive's parameter list.
 */
#ifndef PN_SCENE_BUILD_H
#define PN_SCENE_BUILD_H

#include "scene/params.h"
#include "scene/scene.h"

/* How an RGB / blackbody / spectrum value is turned into linear RGB. */
typedef enum pn_spectrum_use {
    PN_SPECTRUM_ALBEDO = 0,    /* reflectances: clamped to [0, 1] */
    PN_SPECTRUM_UNBOUNDED = 1, /* eta, k, sigma: taken as they are */
    PN_SPECTRUM_ILLUMINANT = 2 /* emission: blackbody and named illuminants (stdillum-*)
                                   normalised to luminance 1, keeping their colour */
} pn_spectrum_use;

/* Reads parameter `name` of type rgb, blackbody or spectrum (numeric lambda/value pairs, a named
 * pbrt-v4 spectrum such as "metal-Cu-eta" / "glass-BK7", or an .spd file relative to base_dir) as
 * linear RGB. Absent: *out = def, *found = false (found may be NULL). Wrong type or values: err at
 * the parameter's location, PN_ERROR_BAD_INPUT. */
pn_status pn_params_rgb(const pn_params *ps, const char *name, vec3 def, pn_spectrum_use use, vec3 *out, bool *found,
                        pn_err *err);

/* A spectral quantity read as one number at wavelength lambda_nm: a float, a numeric or file
 * spectrum evaluated there (end values held outside its range), a named spectrum's green value
 * (glasses: their index at 550 nm), or the green channel of an rgb. Absent: *out = def. */
pn_status pn_params_spectrum_value(const pn_params *ps, const char *name, double lambda_nm, double def, double *out,
                                   bool *found, pn_err *err);

/* RGB of a named pbrt-v4 spectrum (metal-Cu-eta, glass-BK7, stdillum-D65, ...); false if unknown. */
bool pn_named_spectrum_rgb(const char *name, vec3 *out);

/* The temperature of parameter `name` when it is a "blackbody" value (spectral mode emits the
 * black body itself), else 0. */
float pn_params_blackbody_kelvin(const pn_params *ps, const char *name);

/* The tabulated spectrum of emission parameter `name` for spectral mode, when it is a "spectrum"
 * value given as numbers, an .spd file, or a named illuminant (stdillum-A, -D50, -D65, -F1 ... -F12,
 * illum-acesD60: the CIE tables of spectral/cie.h): a pn_spd owned by the scene (scene->spds), else NULL (*out; absent,
 * rgb, blackbody, other names). Call after pn_params_rgb accepted the parameter. */
struct pn_spd;
pn_status pn_params_light_spectrum(struct pn_scene_s *scene, const pn_params *ps, const char *name,
                                   const struct pn_spd **out, pn_err *err);

/* Linear sRGB of a blackbody at `kelvin`, normalised to luminance 1. */
vec3 pn_blackbody_rgb(double kelvin);

/* Linear sRGB of a piecewise linear spectrum given as (lambda, value) pairs (value_count numbers,
 * increasing lambdas), converted as pn_params_rgb does for `use`. */
vec3 pn_spectrum_pairs_rgb(const double *pairs, int value_count, pn_spectrum_use use);

/* The shared image table (scene->images): decodes `path` (already resolved) with `gamma` as
 * pn_image_read_file takes it, or returns the index of the same file decoded with the same gamma
 * earlier. On failure err holds the image reader's message (without a location). */
pn_status pn_scene_image(struct pn_scene_s *scene, const char *path, float gamma, int *out_index, pn_err *err);
/* The pyramid of image `image` under `wrap` (scene->mipmaps), built on first use. */
pn_status pn_scene_mipmap(struct pn_scene_s *scene, int image, pn_wrap_mode wrap, int *out_index, pn_err *err);

/* A material input that is a constant or a named texture ("texture name" "tex"): float (is_float,
 * value in .x of the texref) or RGB/spectrum. Undefined texture names are an error at the
 * parameter's location. Absent: constant `def`. */
pn_status pn_params_texref(struct pn_scene_s *scene, const pn_params *ps, const char *name, bool is_float, vec3 def,
                           pn_texref *out, pn_err *err);

/* pn_params_texref with the conversion of constant RGB/spectrum values chosen by `use`
 * (pn_params_texref uses PN_SPECTRUM_ALBEDO, clamping with a warning; eta and k of conductors
 * need PN_SPECTRUM_UNBOUNDED). */
pn_status pn_params_texref_use(struct pn_scene_s *scene, const pn_params *ps, const char *name, bool is_float, vec3 def,
                               pn_spectrum_use use, pn_texref *out, pn_err *err);

/* Index of the last texture called `name` of the given kind (float or spectrum), or -1. */
int pn_scene_find_texture_typed(const struct pn_scene_s *scene, const char *name, bool is_float);

/* Texture "name" "float"|"spectrum" "class" params: appends to scene->textures (and decodes image
 * files into scene->images, sharing identical files). loc is the directive's location. */
pn_status pn_texture_from_pbrt(struct pn_scene_s *scene, const char *name, const char *value_type,
                               const char *class_name, const pn_params *ps, pn_err *err);

/* Index of the last texture called `name`, or -1. */
int pn_scene_find_texture(const struct pn_scene_s *scene, const char *name);

/* Material "type" params / MakeNamedMaterial "name" "string type" ...: appends a material mapped
 * as ARCHITECTURE.md says (with its one-line description) and returns its index in *out.
 * name is "" for anonymous Material directives. */
pn_status pn_material_from_pbrt(struct pn_scene_s *scene, const char *type, const char *name, const pn_params *ps,
                                int *out, pn_err *err);

/* Index of the last material called `name`, or -1. */
int pn_scene_find_material(const struct pn_scene_s *scene, const char *name);

/* LightSource "type" params under the current transform: appends to scene->light_defs
 * (point, spot, distant, infinite, goniometric, projection). */
pn_status pn_light_from_pbrt(struct pn_scene_s *scene, const char *type, const pn_params *ps,
                             const mat4 *world_from_light, pn_err *err);

/* AreaLightSource "diffuse" params. radiance = L * scale; when "power" is given, power > 0 and
 * pn_area_light_apply_power must be called for the shape it is attached to. */
typedef struct pn_area_light_desc {
    pn_emission emission;
    double power;      /* 0 = not given */
    float photometric; /* pbrt-v4 SpectrumToPhotometric(L): 1 for rgb, else luminance(L) */
} pn_area_light_desc;

pn_status pn_area_light_from_pbrt(struct pn_scene_s *scene, const char *type, const pn_params *ps,
                                  pn_area_light_desc *out, pn_err *err);

/* pbrt-v4: radiance *= power / (pi * (two_sided ? 2 : 1) * A * photometric), A the area of one
 * pbrt shape. `shape_type` is the Shape directive's type: for "trianglemesh", "plymesh" and
 * "loopsubdiv" every triangle is a shape, for "bilinearmesh" every patch (two triangles), and
 * the factor per triangle is left to the light builder (emission.per_shape); for the other types
 * the whole shape is one and `area` (its world-space area) is used. */
void pn_area_light_apply_power(pn_area_light_desc *desc, double area, const char *shape_type);

#endif
