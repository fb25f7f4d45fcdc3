/* lightdefs.c — pbrt-v4 LightSource and AreaLightSource directives as scene records.
 *
 * Light spectra are read with PN_SPECTRUM_ILLUMINANT (rgb as given; blackbody and other spectra
 * normalised to luminance 1, as pbrt-v4 divides every light spectrum by its photometric value).
 * "power" and "illuminance" divide by that photometric value too, which pbrt-v4's
 * SpectrumToPhotometric takes from the illuminant alone for an rgb spectrum (util/spectrum.cpp):
 * the magnitude of an "rgb" value is kept as a multiplier, so "rgb I [2 2 2]" with "power" P
 * emits 2 P. Below, photometric(S) is 1 for an rgb value and luminance(S) (1 after the
 * normalisation above) for the other spectrum forms.
 *
 *  point        I (default 1) * scale at world_from_light * from (default origin). "power" P
 *               (when > 0) rescales the intensity to I * scale * P / (4 pi photometric(I)).
 *  spot         as point, aimed from "from" (0,0,0) to "to" (0,0,1); cone of "coneangle" (30
 *               degrees) with a smooth falloff over the last "conedeltaangle" (5) degrees
 *               (pbrt-v4's name; "conedelta" is not a pbrt-v4 parameter and is reported
 *               unused): cos_total_width = cos(coneangle), cos_falloff_start = cos(coneangle -
 *               conedeltaangle); the intensity is I * smoothstep(cos theta, cos_total_width,
 *               cos_falloff_start) (lights/light_sample.c). "power" P: I * scale * P /
 *               (2 pi ((1 - cosStart) + (cosStart - cosEnd) / 2) photometric(I)).
 *  distant      L * scale arriving from world_from_light * (from - to) (defaults (0,0,0) and
 *               (0,0,1)). "illuminance" E rescales to L * scale * E / photometric(L); "power" is
 *               not meaningful for it and is ignored with a warning.
 *  infinite     constant "L" * scale, or the image "filename" scaled by "scale". pbrt-v4 expects
 *               an equal-area octahedral (square) image; a non-square image is read as a
 *               latitude-longitude map with a warning. "illuminance" E: for a constant L,
 *               L * scale * E / (pi photometric(L)); for an image, scale * E / k where k is
 *               pbrt-v4's own estimate of the map's upper-hemisphere illuminance: the sum over
 *               texels with z > 0 of luminance * cos(theta), times 2 pi / (w h). (A texel of
 *               the equal-area map covers 4 pi / (w h), so k is half the true illuminance and
 *               the map delivers 2 E; penumbra reproduces pbrt-v4's result. A latitude-longitude
 *               map uses half its true texel solid angles, (pi / w) (pi / h) sin(theta), to
 *               match.) "portal" is ignored with a warning.
 *  goniometric  I * scale at world_from_light * origin, modulated by its image: a square map in
 *               pbrt-v4's equal-area octahedral mapping, of the light's frame with y and z
 *               swapped (lights/lights.h, pn_gonio); "power" P gives I * scale * P / (4 pi
 *               photometric(I) mean(image)).
 *  projection   scale * the image "filename" shone through a perspective frustum of "fov" (90)
 *               degrees from world_from_light * origin (projection_from_pbrt, lights/projection.c);
 *               "power" P gives scale * P / (A mean(luminance(rgb) cos^3)), as pbrt-v4.
 *
 * AreaLightSource "diffuse": radiance = L * scale (default L = 1), "twosided", and "power" P
 * normalised per pbrt-v4 shape (scene.cpp creates one DiffuseAreaLight per shape, and each
 * triangle of a mesh, each patch of a bilinear mesh, is its own shape): radiance = L * scale *
 * P / (pi (twosided ? 2 : 1) A photometric(L)) with A the area of that triangle / patch / disk /
 * sphere / cylinder (pn_area_light_apply_power). An emission image ("filename") is not supported:
 * L is used instead, with a warning.
 */
#include "scene/build.h"

#include "lights/lights.h"
#include "scene/parser_internal.h"
#include "scene/photometry.h"
#include "scene/sky.h"
#include "spectral/transport.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PN_PI_D 3.14159265358979323846

static pn_status error_at(pn_srcloc loc, pn_status status, pn_err *err, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static pn_status error_at(pn_srcloc loc, pn_status status, pn_err *err, const char *fmt, ...) {
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pn_err_set(err, status, "%s:%d:%d: %s", loc.file ? loc.file : "?", loc.line, loc.column, msg);
}

/* Warns about a parameter that is understood but has no effect here. */
static void warn_ignored(struct pn_scene_s *scene, const pn_params *ps, const char *name, const char *why) {
    const pn_param *p = pn_params_find(ps, name);
    if (p) pn_warn_at(scene, p->loc, "\"%s\" %s", name, why);
}

/* Reads "power" (or another positive scalar); 0 when absent or not positive. */
static pn_status read_positive(const pn_params *ps, const char *name, double *out, pn_err *err) {
    double v = -1.0;
    pn_status st = pn_params_float(ps, name, -1.0, &v, err);
    if (st != PN_OK) return st;
    *out = v > 0.0 && isfinite(v) ? v : 0.0;
    return PN_OK;
}

/* pbrt-v4's estimate of the illuminance an environment image delivers to a surface facing +z in
 * light space (lights.cpp, Light::Create "illuminance"): the sum over texels above the horizon of
 * luminance * cos(theta) * 2 pi / (w h), half the texel's true solid angle 4 pi / (w h). The
 * latitude-longitude layout (not pbrt-v4's) uses half its true texel solid angle likewise,
 * (pi / w) (pi / h) sin(theta), so both layouts of one map are scaled alike. */
static double image_illuminance(const pn_texture_image *img, bool equal_area) {
    double sum = 0.0;
    for (int y = 0; y < img->height; y++) {
        for (int x = 0; x < img->width; x++) {
            float u = ((float)x + 0.5f) / (float)img->width, v = ((float)y + 0.5f) / (float)img->height;
            double cos_theta, solid_angle;
            if (equal_area) {
                cos_theta = pn_equal_area_square_to_sphere(u, v).z;
                solid_angle = 2.0 * PN_PI_D / ((double)img->width * (double)img->height);
            } else {
                double theta = (double)v * PN_PI_D;
                cos_theta = cos(theta);
                solid_angle = (PN_PI_D / img->width) * (PN_PI_D / img->height) * sin(theta);
            }
            if (cos_theta <= 0.0) continue;
            const float *px = img->rgb + 3 * ((size_t)y * (size_t)img->width + (size_t)x);
            sum += (double)v3_luminance(v3(px[0], px[1], px[2])) * cos_theta * solid_angle;
        }
    }
    return sum;
}

/* pbrt-v4's SpectrumToPhotometric for a light spectrum read into `rgb` from parameter `name`: an
 * rgb value counts by its illuminant only (1 here), the other forms by their luminance. */
static double photometric(const pn_params *ps, const char *name, vec3 rgb) {
    const pn_param *p = pn_params_find(ps, name);
    if (!p || p->type == PN_PT_RGB) return 1.0;
    return (double)v3_luminance(rgb);
}

/* Intensity rescaled to emit `power` over the solid-angle factor k_e; phot is photometric(). */
static vec3 apply_power(vec3 intensity, double phot, double power, double k_e) {
    if (!(power > 0.0) || !(phot > 0.0) || !(k_e > 0.0)) return intensity;
    return v3_scale(intensity, (float)(power / (k_e * phot)));
}

static pn_status load_image_param(struct pn_scene_s *scene, const pn_params *ps, const char *file, int *index,
                                  pn_err *err) {
    char *path = pn_path_resolve(ps->base_dir, file);
    if (!path) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    pn_err ierr;
    pn_err_init(&ierr);
    pn_status st = pn_scene_image(scene, path, 0.0f, index, &ierr);
    free(path);
    if (st == PN_ERROR_OUT_OF_MEMORY) return pn_err_set(err, st, "%s", ierr.message);
    if (st != PN_OK)
        return pn_param_error(pn_params_find(ps, "filename"), err, "cannot read light image: %s", ierr.message);
    return PN_OK;
}

/* LightSource "projection" (pbrt-v4's ProjectionLight::Create): "filename" (required), "fov"
 * (90 degrees, across the image's shorter side; must lie in (0, 180)), "scale" (1), "power"
 * (when > 0: scale * power / pn_projection_unit_power). The image's RGB is the illuminant's
 * colour as given, so scale * rgb is the intensity (W/sr). pbrt-v4 flips y of the light's frame
 * (renderFromLight * Scale(1, -1, 1)); the flip is part of the stored transform. */
static pn_status projection_from_pbrt(struct pn_scene_s *scene, const pn_params *ps, pn_light_def *d, pn_err *err) {
    double scale = 1.0, power = 0.0, fov = 90.0;
    const char *file = NULL;
    pn_status st = pn_params_float(ps, "scale", 1.0, &scale, err);
    if (st == PN_OK) st = read_positive(ps, "power", &power, err);
    if (st == PN_OK) st = pn_params_float(ps, "fov", 90.0, &fov, err);
    if (st == PN_OK) st = pn_params_string(ps, "filename", "", &file, err);
    if (st != PN_OK) return st;
    if (!(fov > 0.0 && fov < 180.0))
        return pn_param_error(pn_params_find(ps, "fov"), err,
                              "projection light: \"fov\" %g is outside (0, 180) degrees", fov);
    if (!file[0])
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err,
                        "projection light: \"filename\" (the projected image) is required");
    st = load_image_param(scene, ps, file, &d->image, err);
    if (st != PN_OK) return st;
    const pn_texture_image *img = &scene->images[d->image];
    for (size_t i = 0; i < 3 * (size_t)img->width * (size_t)img->height; i++)
        if (!isfinite(img->rgb[i]))
            return pn_param_error(pn_params_find(ps, "filename"), err,
                                  "projection light image \"%s\" has infinite or not-a-number pixels", file);
    if (power > 0.0) {
        double k = pn_projection_unit_power(img->rgb, img->width, img->height, fov);
        if (k > 0.0)
            scale *= power / k;
        else
            warn_ignored(scene, ps, "power", "cannot be met by a black image; ignored");
    }
    d->kind = PN_LIGHTDEF_PROJECTION;
    d->fov_deg = (float)fov;
    d->intensity = v3((float)scale, (float)scale, (float)scale);
    d->position = mat4_apply_point(&d->world_from_light, v3(0, 0, 0));
    d->world_from_light = mat4_mul(d->world_from_light, mat4_scale(1.0, -1.0, 1.0));
    if (!mat4_inverse(d->world_from_light, &d->light_from_world))
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "LightSource \"projection\" under a singular transform");
    return PN_OK;
}

/* The scene's photometric file at `path` (resolved), read once however many lights use it. */
static pn_status scene_photometry(struct pn_scene_s *scene, const pn_params *ps, const char *file, int *index,
                                  pn_err *err) {
    char *path = pn_path_resolve(ps->base_dir, file);
    if (!path) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    for (int i = 0; i < scene->photometry_count; i++)
        if (strcmp(scene->photometries[i]->path, path) == 0) {
            *index = i;
            free(path);
            return PN_OK;
        }
    pn_photometry **grown = realloc(scene->photometries, (size_t)(scene->photometry_count + 1) * sizeof *grown);
    if (!grown) {
        free(path);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    scene->photometries = grown;
    pn_err perr;
    pn_err_init(&perr);
    pn_photometry *p = NULL;
    pn_status st = pn_photometry_read(path, path, &p, &perr);
    free(path);
    if (st != PN_OK) {
        const pn_param *fp = pn_params_find(ps, "filename");
        pn_srcloc loc = fp ? fp->loc : ps->loc;
        return pn_err_set(err, st, "%s (the goniometric light's \"filename\" at %s:%d:%d)", perr.message,
                          loc.file ? loc.file : "?", loc.line, loc.column);
    }
    *index = scene->photometry_count;
    scene->photometries[scene->photometry_count++] = p;
    return PN_OK;
}

/* LightSource "goniometric" with an IES or EULUMDAT "filename" (docs/luminaires.md): the file's
 * candela, times "scale", times the tilt table's factor at "tilt" degrees (TILT=INCLUDE files),
 * and with "power" P > 0 rescaled so the luminaire emits P lumens (times "scale", as pbrt-v4
 * keeps scale on top of power). "I" gives the colour only: it is divided by its luminance, so a
 * luminaire of I candela renders luminance Y = I (docs/units.md). Light space: nadir -z, C = 0
 * along +x (scene/photometry.h); no y-z swap, unlike pbrt-v4's image-based goniometric light. */
static pn_status goniometric_from_photometry(struct pn_scene_s *scene, const pn_params *ps, const char *file, vec3 I,
                                             double scale, double power, pn_light_def *d, pn_err *err) {
    double tilt = 0.0;
    pn_status st = pn_params_float(ps, "tilt", 0.0, &tilt, err);
    if (st != PN_OK) return st;
    if (!isfinite(tilt) || tilt < 0.0 || tilt > 180.0)
        return pn_param_error(pn_params_find(ps, "tilt"), err, "\"tilt\" %g is outside 0..180 degrees", tilt);
    double y = (double)v3_luminance(I);
    if (!(y > 0.0) || !v3_is_finite(I))
        return pn_param_error(pn_params_find(ps, "I"), err,
                              "the colour \"I\" of a measured luminaire needs a positive luminance");
    int index = -1;
    st = scene_photometry(scene, ps, file, &index, err);
    if (st != PN_OK) return st;
    const pn_photometry *p = scene->photometries[index];
    if (!p->tilt_count)
        warn_ignored(scene, ps, "tilt", "has no effect: the file has no tilt table (TILT=INCLUDE); ignored");
    double factor = scale * pn_photometry_tilt_factor(p, tilt);
    if (power > 0.0) factor *= power / p->lumens;
    d->photometry = index;
    d->photometry_scale = factor;
    d->intensity = v3_scale(I, (float)(factor * p->peak_cd / y));
    d->position = mat4_apply_point(&d->world_from_light, v3(0, 0, 0));
    return PN_OK;
}

/* Appends *d to the scene's light definitions, its source named by ps's location. */
static pn_status append_light_def(struct pn_scene_s *scene, pn_light_def *d, const pn_params *ps, pn_err *err) {
    char source[512];
    snprintf(source, sizeof source, "%s:%d:%d", ps->loc.file ? ps->loc.file : "?", ps->loc.line, ps->loc.column);
    size_t n = strlen(source) + 1;
    d->source = malloc(n);
    if (!d->source ||
        !pn_grow_for_append((void **)&scene->light_defs, scene->light_def_count, sizeof *scene->light_defs)) {
        free(d->source);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for a light");
    }
    memcpy(d->source, source, n);
    scene->light_defs[scene->light_def_count++] = *d;
    return PN_OK;
}

pn_status pn_light_from_pbrt(struct pn_scene_s *scene, const char *type, const pn_params *ps,
                             const mat4 *world_from_light, pn_err *err) {
    pn_light_def d;
    memset(&d, 0, sizeof d);
    d.image = -1;
    d.photometry = -1;
    d.world_from_light = *world_from_light;
    if (!mat4_is_finite(*world_from_light) || !mat4_inverse(*world_from_light, &d.light_from_world))
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "LightSource \"%s\" under a singular transform", type);

    pn_status st = PN_OK;
    const vec3 one = v3(1, 1, 1);
    double scale = 1.0, power = 0.0;
    if (strcmp(type, "projection") == 0) {
        st = projection_from_pbrt(scene, ps, &d, err);
        if (st != PN_OK) return st;
    } else if (strcmp(type, "point") == 0 || strcmp(type, "spot") == 0 || strcmp(type, "goniometric") == 0) {
        vec3 I;
        vec3 from = v3(0, 0, 0), to = v3(0, 0, 1);
        st = pn_params_rgb(ps, "I", one, PN_SPECTRUM_ILLUMINANT, &I, NULL, err);
        if (st == PN_OK) st = pn_params_float(ps, "scale", 1.0, &scale, err);
        if (st == PN_OK) st = read_positive(ps, "power", &power, err);
        if (st == PN_OK && strcmp(type, "goniometric") != 0) st = pn_params_vec3(ps, "from", from, &from, err);
        if (st != PN_OK) return st;
        d.intensity = v3_scale(I, (float)scale);
        d.kelvin = pn_params_blackbody_kelvin(ps, "I");
        st = pn_params_light_spectrum(scene, ps, "I", &d.spd, err);
        if (st != PN_OK) return st;
        d.position = mat4_apply_point(world_from_light, from);
        if (strcmp(type, "point") == 0) {
            d.kind = PN_LIGHTDEF_POINT;
            d.intensity = apply_power(d.intensity, photometric(ps, "I", I), power, 4.0 * PN_PI_D);
        } else if (strcmp(type, "spot") == 0) {
            double cone = 30.0, delta = 5.0;
            st = pn_params_vec3(ps, "to", to, &to, err);
            if (st == PN_OK) st = pn_params_float(ps, "coneangle", 30.0, &cone, err);
            if (st == PN_OK) st = pn_params_float(ps, "conedeltaangle", 5.0, &delta, err);
            if (st != PN_OK) return st;
            vec3 axis = mat4_apply_vector(world_from_light, v3_sub(to, from));
            if (!(v3_length(axis) > 0.0f) || !v3_is_finite(axis))
                return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "spot light with \"from\" equal to \"to\"");
            d.kind = PN_LIGHTDEF_SPOT;
            d.direction = v3_normalize(axis);
            double rad = PN_PI_D / 180.0;
            double cos_end = cos(cone * rad), cos_start = cos((cone - delta) * rad);
            d.cos_total_width = (float)cos_end;
            d.cos_falloff_start = (float)cos_start;
            double k_e = 2.0 * PN_PI_D * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0);
            d.intensity = apply_power(d.intensity, photometric(ps, "I", I), power, k_e);
        } else {
            d.kind = PN_LIGHTDEF_GONIOMETRIC;
            const char *file = NULL;
            st = pn_params_string(ps, "filename", "", &file, err);
            if (st != PN_OK) return st;
            bool measured = pn_photometry_is_file(file);
            if (measured) {
                st = goniometric_from_photometry(scene, ps, file, I, scale, power, &d, err);
                if (st != PN_OK) return st;
            }
            if (!measured) warn_ignored(scene, ps, "tilt", "applies to IES files with TILT=INCLUDE only; ignored");
            if (file[0] && !measured) {
                st = load_image_param(scene, ps, file, &d.image, err);
                if (st != PN_OK) return st;
                const pn_texture_image *img = &scene->images[d.image];
                if (img->width != img->height) {
                    const pn_param *fp = pn_params_find(ps, "filename");
                    return pn_param_error(fp, err,
                                          "the image of a goniometric light must be square (pbrt-v4's equal-area "
                                          "mapping); \"%s\" is %dx%d",
                                          file, img->width, img->height);
                }
            }
            /* pbrt-v4: the power of a goniometric light is 4 pi I times the image's mean. */
            double mean = 1.0;
            if (d.image >= 0) {
                const pn_texture_image *img = &scene->images[d.image];
                double sum = 0.0;
                size_t texels = (size_t)img->width * (size_t)img->height;
                for (size_t i = 0; i < 3 * texels; i++) sum += (double)img->rgb[i];
                mean = texels ? sum / (3.0 * (double)texels) : 0.0;
            }
            if (!measured) d.intensity = apply_power(d.intensity, photometric(ps, "I", I), power, 4.0 * PN_PI_D * mean);
        }
    } else if (strcmp(type, "distant") == 0) {
        vec3 L, from = v3(0, 0, 0), to = v3(0, 0, 1);
        double illuminance = 0.0;
        st = pn_params_rgb(ps, "L", one, PN_SPECTRUM_ILLUMINANT, &L, NULL, err);
        if (st == PN_OK) st = pn_params_float(ps, "scale", 1.0, &scale, err);
        if (st == PN_OK) st = pn_params_vec3(ps, "from", from, &from, err);
        if (st == PN_OK) st = pn_params_vec3(ps, "to", to, &to, err);
        if (st == PN_OK) st = read_positive(ps, "illuminance", &illuminance, err);
        if (st != PN_OK) return st;
        vec3 w = mat4_apply_vector(world_from_light, v3_sub(from, to));
        if (!(v3_length(w) > 0.0f) || !v3_is_finite(w))
            return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "distant light with \"from\" equal to \"to\"");
        d.kind = PN_LIGHTDEF_DISTANT;
        d.kelvin = pn_params_blackbody_kelvin(ps, "L");
        st = pn_params_light_spectrum(scene, ps, "L", &d.spd, err);
        if (st != PN_OK) return st;
        d.direction = v3_normalize(w);
        d.intensity = apply_power(v3_scale(L, (float)scale), photometric(ps, "L", L), illuminance, 1.0);
        warn_ignored(scene, ps, "power", "is not supported for distant lights (use \"illuminance\"); ignored");
    } else if (strcmp(type, "infinite") == 0) {
        vec3 L;
        bool has_L = false;
        const char *file = NULL;
        double illuminance = 0.0;
        st = pn_params_rgb(ps, "L", one, PN_SPECTRUM_ILLUMINANT, &L, &has_L, err);
        if (st == PN_OK) st = pn_params_float(ps, "scale", 1.0, &scale, err);
        if (st == PN_OK) st = pn_params_string(ps, "filename", "", &file, err);
        if (st == PN_OK) st = read_positive(ps, "illuminance", &illuminance, err);
        const char *sky = "";
        if (st == PN_OK) st = pn_sky_requested(ps, &sky, err);
        if (st != PN_OK) return st;
        d.kind = PN_LIGHTDEF_INFINITE;
        warn_ignored(scene, ps, "portal", "is not supported; the infinite light is sampled without its portal");
        if (sky[0]) { /* penumbra's daylight skies (scene/sky.c), in absolute units */
            if (has_L || file[0])
                return error_at(ps->loc, PN_ERROR_BAD_INPUT, err,
                                "infinite light: \"sky\" cannot be given with \"L\" or \"filename\"");
            st = pn_sky_image(scene, ps, sky, illuminance, &d.image, err);
            if (st != PN_OK) return st;
            d.equal_area = true;
            d.intensity = v3((float)scale, (float)scale, (float)scale);
            /* The clear sky's sun: a distant light of its own, from the sun's direction, with the
             * illuminance normal to it that gives the direct horizontal illuminance asked for. */
            vec3 sun_dir;
            double sun_lux = 0.0;
            if (strcmp(sky, "cie-clear") == 0 && (st = pn_sky_sun(ps, &sun_dir, &sun_lux, err)) != PN_OK) return st;
            if (sun_lux > 0.0) {
                pn_light_def sun = d;
                sun.kind = PN_LIGHTDEF_DISTANT;
                sun.image = -1;
                sun.equal_area = false;
                sun.direction = v3_normalize(mat4_apply_vector(world_from_light, sun_dir));
                sun.intensity = v3_scale(v3((float)sun_lux, (float)sun_lux, (float)sun_lux), (float)scale);
                st = append_light_def(scene, &sun, ps, err);
                if (st != PN_OK) return st;
            }
        } else if (file[0]) {
            if (has_L)
                return error_at(ps->loc, PN_ERROR_BAD_INPUT, err,
                                "infinite light: \"L\" and \"filename\" cannot both be given");
            st = load_image_param(scene, ps, file, &d.image, err);
            if (st != PN_OK) return st;
            const pn_texture_image *img = &scene->images[d.image];
            d.equal_area = img->width == img->height;
            if (!d.equal_area) {
                const pn_param *p = pn_params_find(ps, "filename");
                pn_warn_at(scene, p ? p->loc : ps->loc,
                           "environment image \"%s\" is %dx%d, not square (pbrt-v4's equal-area octahedral layout); "
                           "read as a latitude-longitude map",
                           file, img->width, img->height);
            }
            if (illuminance > 0.0) {
                double e = image_illuminance(img, d.equal_area);
                if (e > 0.0)
                    scale *= illuminance / e;
                else
                    warn_ignored(scene, ps, "illuminance", "cannot be met by a black upper hemisphere; ignored");
            }
            d.intensity = v3((float)scale, (float)scale, (float)scale);
        } else {
            d.intensity = apply_power(v3_scale(L, (float)scale), photometric(ps, "L", L), illuminance, PN_PI_D);
        }
    } else {
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "unknown light type \"%s\"", type);
    }
    if (!v3_is_finite(d.intensity) || !v3_is_finite(d.position))
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "LightSource \"%s\" has non-finite values", type);
    return append_light_def(scene, &d, ps, err);
}

pn_status pn_area_light_from_pbrt(struct pn_scene_s *scene, const char *type, const pn_params *ps,
                                  pn_area_light_desc *out, pn_err *err) {
    memset(out, 0, sizeof *out);
    if (strcmp(type, "diffuse") != 0)
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "unknown area light type \"%s\" (only \"diffuse\")", type);
    vec3 L;
    double scale = 1.0, power = 0.0;
    bool two_sided = false;
    const char *file = NULL;
    pn_status st = pn_params_rgb(ps, "L", v3(1, 1, 1), PN_SPECTRUM_ILLUMINANT, &L, NULL, err);
    if (st == PN_OK) st = pn_params_float(ps, "scale", 1.0, &scale, err);
    if (st == PN_OK) st = pn_params_bool(ps, "twosided", false, &two_sided, err);
    if (st == PN_OK) st = read_positive(ps, "power", &power, err);
    if (st == PN_OK) st = pn_params_string(ps, "filename", "", &file, err);
    if (st != PN_OK) return st;
    if (file[0])
        warn_ignored(scene, ps, "filename", "(an emission image) is not supported; the constant \"L\" is used");
    out->emission.radiance = v3_scale(L, (float)scale);
    out->emission.two_sided = two_sided;
    out->emission.kelvin = pn_params_blackbody_kelvin(ps, "L");
    out->emission.kelvin_scale = (float)pn_blackbody_unit_scale(out->emission.kelvin);
    st = pn_params_light_spectrum(scene, ps, "L", &out->emission.spd, err);
    if (st != PN_OK) return st;
    out->power = power;
    out->photometric = (float)photometric(ps, "L", L);
    if (!v3_is_finite(out->emission.radiance))
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "AreaLightSource has non-finite radiance");
    return PN_OK;
}

void pn_area_light_apply_power(pn_area_light_desc *desc, double area, const char *shape_type) {
    desc->emission.per_shape = 0;
    if (!(desc->power > 0.0) || !(desc->photometric > 0.0f)) return;
    double k = PN_PI_D * (desc->emission.two_sided ? 2.0 : 1.0) * (double)desc->photometric;
    const char *t = shape_type ? shape_type : "";
    if (strcmp(t, "trianglemesh") == 0 || strcmp(t, "plymesh") == 0 || strcmp(t, "loopsubdiv") == 0) {
        desc->emission.per_shape = 1;
    } else if (strcmp(t, "bilinearmesh") == 0) {
        desc->emission.per_shape = 2;
    } else {
        if (!(area > 0.0)) return;
        k *= area;
    }
    /* per_shape: radiance per unit of 1 / area; the light builder divides by each shape's area. */
    desc->emission.radiance = v3_scale(desc->emission.radiance, (float)(desc->power / k));
}
