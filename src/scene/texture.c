/* texture.c — pbrt-v4 Texture directives, texture-valued material inputs, the shared table of
 * decoded images, and texture evaluation at surface (u, v).
 *
 * Supported classes and how they are stored (pn_texture):
 *  - imagemap: "filename" (relative to the directive's folder), "encoding" ("sRGB" default,
 *    "linear", "gamma g"), "scale", "invert", "wrap" (repeat, clamp, black), the uv mapping
 *    "uscale" "vscale" "udelta" "vdelta". As in pbrt-v4 the encoding applies to PNG files (8 and
 *    16 bit) only: other 8-bit formats (TGA, JPEG, BMP, ...) are always decoded with the sRGB
 *    curve (a different "encoding" is reported as ignored), EXR / PFM / HDR are linear.
 *    "filter" (point, bilinear (default), trilinear; ewa read as trilinear) picks how the
 *    image's pyramid is read (scene/mipmap.c) and the float lookup below; "maxanisotropy" is
 *    ignored. Files are decoded once per (path, encoding) into scene->images, pyramids built
 *    once per (image, wrap mode) into scene->mipmaps.
 *  - constant ("value"), scale ("tex" * "scale"), mix ((1 - "amount") "tex1" + "amount" "tex2"),
 *    checkerboard (2D; "tex1" on cells where floor(s) + floor(t) is even, else "tex2").
 *  - directionmix and dots become a mix with amount 0.5 of their two inputs; bilerp the
 *    average of its four corners; fbm, wrinkled, windy, marble and ptex a constant 0.5. Each
 *    substitution is reported with a warning.
 * Mappings other than "uv" (spherical, cylindrical, planar) are replaced by uv with a warning.
 *
 * Evaluation follows pbrt-v4: s = su * u + du, t = sv * v + dv; an image is looked up at
 * (s, 1 - t) because its row 0 is the top, in the pyramid level the lookup's footprint (the
 * hit's uv derivatives times su, sv) selects (pn_mipmap_lookup); the value is multiplied by
 * "scale", inverted (1 - x) if asked, and clamped at 0.
 * Float textures read from RGB images as pbrt-v4's MIPMap does: the average of the three
 * channels for the "bilinear" (default) and "trilinear" filters, the first channel for "point"
 * and "ewa" (its Texel lookup); the value is then scaled, inverted (1 - x, clamped at 0). Float
 * results are returned in all three channels, and float constants are stored the same way.
 *
 * Texture inputs refer to textures by index; a texture can only refer to textures defined before
 * it, so evaluation always terminates.
 */
#include "scene/build.h"

#include "io/image.h"
#include "scene/parser_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- the shared image table ----------------------------------------------------------------- */

/* The table key: the path, plus the encoding when it is not the default sRGB curve. */
static void image_key(const char *path, float gamma, char *key, size_t size) {
    if (gamma == 0.0f)
        snprintf(key, size, "%s", path);
    else if (gamma == 1.0f)
        snprintf(key, size, "%s (linear)", path);
    else
        snprintf(key, size, "%s (gamma %g)", path, (double)gamma);
}

pn_status pn_scene_image(struct pn_scene_s *scene, const char *path, float gamma, int *out_index, pn_err *err) {
    *out_index = -1;
    size_t key_size = strlen(path) + 64;
    char *key = malloc(key_size);
    if (!key) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    image_key(path, gamma, key, key_size);
    for (int i = 0; i < scene->image_count; i++) {
        if (scene->images[i].path && strcmp(scene->images[i].path, key) == 0) {
            *out_index = i;
            free(key);
            return PN_OK;
        }
    }
    pn_image img = NULL;
    pn_status st = pn_image_read_file_limit(path, gamma, pn_context_image_pixel_limit(scene->ctx), &img, err);
    if (st != PN_OK) {
        free(key);
        pn_image_free(img);
        return st;
    }
    if (!img || img->layer_count < 1 || img->width <= 0 || img->height <= 0 || !img->layers[0].data) {
        free(key);
        pn_image_free(img);
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%s: empty image", path);
    }
    size_t n = (size_t)img->width * (size_t)img->height;
    float *rgb = NULL;
    if (img->layers[0].channels == 3) {
        rgb = img->layers[0].data; /* take the pixels over */
        img->layers[0].data = NULL;
    } else {
        rgb = malloc(3 * n * sizeof *rgb);
        if (rgb) {
            int ch = img->layers[0].channels;
            for (size_t i = 0; i < n; i++)
                for (int c = 0; c < 3; c++)
                    rgb[3 * i + (size_t)c] = img->layers[0].data[i * (size_t)ch + (size_t)(c < ch ? c : 0)];
        }
    }
    if (!rgb || !pn_grow_for_append((void **)&scene->images, scene->image_count, sizeof *scene->images)) {
        free(rgb);
        free(key);
        pn_image_free(img);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for image \"%s\"", path);
    }
    pn_texture_image *ti = &scene->images[scene->image_count];
    ti->width = img->width;
    ti->height = img->height;
    ti->rgb = rgb;
    ti->path = key;
    *out_index = scene->image_count++;
    pn_image_free(img);
    return PN_OK;
}

/* ---- lookups ---------------------------------------------------------------------------------- */

int pn_scene_find_texture(const struct pn_scene_s *scene, const char *name) {
    for (int i = scene->texture_count - 1; i >= 0; i--)
        if (scene->textures[i].name && strcmp(scene->textures[i].name, name) == 0) return i;
    return -1;
}

int pn_scene_find_texture_typed(const struct pn_scene_s *scene, const char *name, bool is_float) {
    for (int i = scene->texture_count - 1; i >= 0; i--)
        if (scene->textures[i].is_float == is_float && scene->textures[i].name &&
            strcmp(scene->textures[i].name, name) == 0)
            return i;
    return -1;
}

/* ---- texture-valued parameters ---------------------------------------------------------------- */

static pn_texref constant_ref(vec3 v) {
    pn_texref r;
    r.texture = -1;
    r.value = v;
    return r;
}

pn_status pn_params_texref_use(struct pn_scene_s *scene, const pn_params *ps, const char *name, bool is_float, vec3 def,
                               pn_spectrum_use use, pn_texref *out, pn_err *err) {
    if (is_float) def = v3(def.x, def.x, def.x);
    *out = constant_ref(def);
    const pn_param *p = pn_params_find(ps, name);
    if (!p) return PN_OK;
    switch (p->type) {
    case PN_PT_TEXTURE: {
        if (p->str_count != 1) return pn_param_error(p, err, "texture \"%s\" needs one texture name", name);
        const char *tex = p->strs[0];
        int idx = pn_scene_find_texture_typed(scene, tex, is_float);
        if (idx < 0 && !is_float) idx = pn_scene_find_texture_typed(scene, tex, true); /* grey */
        if (idx < 0) {
            if (pn_scene_find_texture(scene, tex) >= 0)
                return pn_param_error(p, err, "\"%s\": texture \"%s\" is a spectrum texture; a float texture is needed",
                                      name, tex);
            return pn_param_error(p, err, "\"%s\": undefined texture \"%s\"", name, tex);
        }
        out->texture = idx;
        out->value = v3(0, 0, 0);
        return PN_OK;
    }
    case PN_PT_FLOAT:
    case PN_PT_INTEGER: {
        if (p->num_count != 1) return pn_param_error(p, err, "\"%s\" needs one value, got %d", name, p->num_count);
        float v = (float)p->nums[0];
        if (!isfinite(v)) return pn_param_error(p, err, "\"%s\" is not finite", name);
        out->value = v3(v, v, v);
        return PN_OK;
    }
    case PN_PT_RGB:
    case PN_PT_SPECTRUM:
    case PN_PT_BLACKBODY: {
        if (is_float) return pn_param_error(p, err, "\"%s\" must be a float or a float texture", name);
        vec3 c;
        pn_status st =
            pn_params_rgb(ps, name, def, use == PN_SPECTRUM_ALBEDO ? PN_SPECTRUM_UNBOUNDED : use, &c, NULL, err);
        if (st != PN_OK) return st;
        if (use == PN_SPECTRUM_ALBEDO && (v3_max_component(c) > 1.0f || fminf(c.x, fminf(c.y, c.z)) < 0.0f)) {
            pn_warn_at(scene, p->loc, "\"%s\" (%g, %g, %g) is outside [0, 1]; clamped", name, (double)c.x, (double)c.y,
                       (double)c.z);
            c = v3_min(v3(1, 1, 1), v3_max(v3(0, 0, 0), c));
        }
        out->value = c;
        return PN_OK;
    }
    default:
        return pn_param_error(p, err, "\"%s\" must be %s or a texture", name,
                              is_float ? "a float" : "an rgb or spectrum value");
    }
}

pn_status pn_params_texref(struct pn_scene_s *scene, const pn_params *ps, const char *name, bool is_float, vec3 def,
                           pn_texref *out, pn_err *err) {
    return pn_params_texref_use(scene, ps, name, is_float, def, PN_SPECTRUM_ALBEDO, out, err);
}

/* ---- Texture directives ----------------------------------------------------------------------- */

static pn_status error_at(pn_srcloc loc, pn_status status, pn_err *err, const char *what) {
    return pn_err_set(err, status, "%s:%d:%d: %s", loc.file ? loc.file : "?", loc.line, loc.column, what);
}

/* Whether `file` ends in `ext` (".png"), ignoring case. */
static bool has_extension(const char *file, const char *ext) {
    size_t n = strlen(file), e = strlen(ext);
    if (n < e) return false;
    for (size_t i = 0; i < e; i++)
        if (tolower((unsigned char)file[n - e + i]) != tolower((unsigned char)ext[i])) return false;
    return true;
}

/* Reads "encoding" into the gamma that pn_image_read_file takes. */
static pn_status read_encoding(const pn_params *ps, float *gamma, pn_err *err) {
    const char *enc = NULL;
    pn_status st = pn_params_string(ps, "encoding", "sRGB", &enc, err);
    if (st != PN_OK) return st;
    if (strcmp(enc, "sRGB") == 0 || strcmp(enc, "srgb") == 0) {
        *gamma = 0.0f;
        return PN_OK;
    }
    if (strcmp(enc, "linear") == 0) {
        *gamma = 1.0f;
        return PN_OK;
    }
    if (strncmp(enc, "gamma", 5) == 0) {
        char *end = NULL;
        double g = strtod(enc + 5, &end);
        while (end && (*end == ' ' || *end == '\t')) end++;
        if (end != enc + 5 && end && *end == '\0' && g > 0.0 && isfinite(g)) {
            *gamma = (float)g;
            return PN_OK;
        }
    }
    return pn_param_error(pn_params_find(ps, "encoding"), err,
                          "unknown encoding \"%s\" (expected \"sRGB\", \"linear\" or \"gamma <value>\")", enc);
}

static pn_status read_wrap(const pn_params *ps, pn_wrap_mode *wrap, pn_err *err) {
    const char *w = NULL;
    pn_status st = pn_params_string(ps, "wrap", "repeat", &w, err);
    if (st != PN_OK) return st;
    if (strcmp(w, "repeat") == 0)
        *wrap = PN_WRAP_REPEAT;
    else if (strcmp(w, "clamp") == 0)
        *wrap = PN_WRAP_CLAMP;
    else if (strcmp(w, "black") == 0)
        *wrap = PN_WRAP_BLACK;
    else if (strcmp(w, "octahedralsphere") == 0)
        *wrap = PN_WRAP_CLAMP;
    else
        return pn_param_error(pn_params_find(ps, "wrap"), err,
                              "unknown wrap mode \"%s\" (expected repeat, clamp or black)", w);
    return PN_OK;
}

static pn_status read_mapping(struct pn_scene_s *scene, const pn_params *ps, pn_texture *t, pn_err *err) {
    const char *mapping = NULL;
    pn_status st = pn_params_string(ps, "mapping", "uv", &mapping, err);
    if (st != PN_OK) return st;
    if (strcmp(mapping, "uv") != 0) {
        const pn_param *p = pn_params_find(ps, "mapping");
        pn_warn_at(scene, p ? p->loc : ps->loc, "texture mapping \"%s\" is not supported; uv mapping used instead",
                   mapping);
        /* The parameters of the other mappings are consumed so they are not reported twice. */
        const char *extra[] = {"v1", "v2", "dimension"};
        for (size_t i = 0; i < sizeof extra / sizeof extra[0]; i++) (void)pn_params_find(ps, extra[i]);
    }
    double su = 1, sv = 1, du = 0, dv = 0;
    if ((st = pn_params_float(ps, "uscale", 1.0, &su, err)) != PN_OK) return st;
    if ((st = pn_params_float(ps, "vscale", 1.0, &sv, err)) != PN_OK) return st;
    if ((st = pn_params_float(ps, "udelta", 0.0, &du, err)) != PN_OK) return st;
    if ((st = pn_params_float(ps, "vdelta", 0.0, &dv, err)) != PN_OK) return st;
    t->su = (float)su;
    t->sv = (float)sv;
    t->du = (float)du;
    t->dv = (float)dv;
    return PN_OK;
}

/* Marks every parameter as used (for substituted classes, whose parameters were all understood
 * and replaced as a whole). */
static void consume_all(const pn_params *ps) {
    for (int i = 0; i < ps->count; i++) (void)pn_params_find(ps, ps->items[i].name);
}

static pn_status texture_imagemap(struct pn_scene_s *scene, const pn_params *ps, pn_texture *t, pn_err *err) {
    const char *file = NULL;
    pn_status st = pn_params_string(ps, "filename", "", &file, err);
    if (st != PN_OK) return st;
    if (!file[0]) return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, "imagemap texture needs a \"filename\"");
    float gamma = 0.0f;
    if ((st = read_encoding(ps, &gamma, err)) != PN_OK) return st;
    /* pbrt-v4 (util/image.cpp Image::Read) applies the encoding to PNG files only (8 and 16
     * bit); its other 8-bit formats (TGA, JPEG, BMP, ...) are always decoded with the sRGB curve
     * and float formats (EXR, PFM, HDR) are linear. */
    bool is_png = has_extension(file, ".png"),
         is_float_format = has_extension(file, ".exr") || has_extension(file, ".pfm") || has_extension(file, ".hdr");
    if (!is_png) {
        const pn_param *ep = pn_params_find(ps, "encoding");
        if (ep && gamma != 0.0f && !is_float_format)
            pn_warn_at(scene, ep->loc,
                       "\"encoding\" applies to PNG files only (pbrt-v4); \"%s\" is decoded with the sRGB curve", file);
        gamma = 0.0f;
    }
    double scale = 1.0;
    bool invert = false;
    if ((st = pn_params_float(ps, "scale", 1.0, &scale, err)) != PN_OK) return st;
    if ((st = pn_params_bool(ps, "invert", false, &invert, err)) != PN_OK) return st;
    if ((st = read_wrap(ps, &t->wrap, err)) != PN_OK) return st;
    const char *filter = NULL;
    if ((st = pn_params_string(ps, "filter", "bilinear", &filter, err)) != PN_OK) return st;
    const bool ewa = strcmp(filter, "ewa") == 0 || strcmp(filter, "EWA") == 0;
    if (strcmp(filter, "bilinear") == 0)
        t->filter = PN_TEXTURE_FILTER_BILINEAR;
    else if (strcmp(filter, "point") == 0)
        t->filter = PN_TEXTURE_FILTER_POINT;
    else if (strcmp(filter, "trilinear") == 0 || ewa)
        t->filter = PN_TEXTURE_FILTER_TRILINEAR; /* EWA read as trilinear (scene/mipmap.c) */
    else
        return pn_param_error(pn_params_find(ps, "filter"), err,
                              "unknown texture filter \"%s\" (expected point, bilinear, trilinear or ewa)", filter);
    t->float_first_channel = t->filter == PN_TEXTURE_FILTER_POINT || ewa;
    double aniso = 8.0;
    if ((st = pn_params_float(ps, "maxanisotropy", 8.0, &aniso, err)) != PN_OK) return st;

    char *path = pn_path_resolve(ps->base_dir, file);
    if (!path) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    pn_err ierr;
    pn_err_init(&ierr);
    int index = -1;
    st = pn_scene_image(scene, path, gamma, &index, &ierr);
    free(path);
    if (st == PN_ERROR_OUT_OF_MEMORY) return pn_err_set(err, st, "%s", ierr.message);
    if (st != PN_OK)
        return pn_param_error(pn_params_find(ps, "filename"), err, "cannot read texture image: %s", ierr.message);
    if ((st = pn_scene_mipmap(scene, index, t->wrap, &t->mipmap, err)) != PN_OK) return st;
    t->kind = PN_TEXTURE_IMAGE;
    t->image = index;
    t->scale = (float)scale;
    t->invert = invert;
    return PN_OK;
}

pn_status pn_texture_from_pbrt(struct pn_scene_s *scene, const char *name, const char *value_type,
                               const char *class_name, const pn_params *ps, pn_err *err) {
    pn_texture t;
    memset(&t, 0, sizeof t);
    char msg[512];
    if (strcmp(value_type, "float") == 0) {
        t.is_float = true;
    } else if (strcmp(value_type, "spectrum") == 0 || strcmp(value_type, "rgb") == 0 ||
               strcmp(value_type, "color") == 0) {
        t.is_float = false;
    } else {
        snprintf(msg, sizeof msg, "texture \"%s\": unknown texture type \"%s\" (expected \"float\" or \"spectrum\")",
                 name, value_type);
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, msg);
    }
    const bool f = t.is_float;
    t.image = -1;
    t.mipmap = -1;
    t.su = t.sv = 1.0f;
    t.scale = 1.0f;
    t.wrap = PN_WRAP_REPEAT;
    t.a = t.b = t.amount = constant_ref(v3(0, 0, 0));
    pn_status st = read_mapping(scene, ps, &t, err);
    if (st != PN_OK) return st;

    const vec3 one = v3(1, 1, 1), zero = v3(0, 0, 0), half = v3(0.5f, 0.5f, 0.5f);
    if (strcmp(class_name, "imagemap") == 0) {
        st = texture_imagemap(scene, ps, &t, err);
    } else if (strcmp(class_name, "constant") == 0) {
        pn_texref r;
        st = pn_params_texref_use(scene, ps, "value", f, one, PN_SPECTRUM_UNBOUNDED, &r, err);
        if (st == PN_OK && r.texture >= 0) {
            /* A constant naming a texture is that texture. */
            t.kind = PN_TEXTURE_SCALE;
            t.a = r;
            t.b = constant_ref(one);
        } else {
            t.kind = PN_TEXTURE_CONSTANT;
            t.value = r.value;
        }
    } else if (strcmp(class_name, "scale") == 0) {
        t.kind = PN_TEXTURE_SCALE;
        st = pn_params_texref_use(scene, ps, "tex", f, one, PN_SPECTRUM_UNBOUNDED, &t.a, err);
        if (st == PN_OK) st = pn_params_texref_use(scene, ps, "scale", true, one, PN_SPECTRUM_UNBOUNDED, &t.b, err);
    } else if (strcmp(class_name, "mix") == 0 || strcmp(class_name, "directionmix") == 0 ||
               strcmp(class_name, "dots") == 0) {
        t.kind = PN_TEXTURE_MIX;
        bool dots = strcmp(class_name, "dots") == 0;
        st = pn_params_texref_use(scene, ps, dots ? "outside" : "tex1", f, dots ? zero : zero, PN_SPECTRUM_UNBOUNDED,
                                  &t.a, err);
        if (st == PN_OK)
            st = pn_params_texref_use(scene, ps, dots ? "inside" : "tex2", f, one, PN_SPECTRUM_UNBOUNDED, &t.b, err);
        if (st == PN_OK && strcmp(class_name, "mix") == 0)
            st = pn_params_texref_use(scene, ps, "amount", true, half, PN_SPECTRUM_UNBOUNDED, &t.amount, err);
        else
            t.amount = constant_ref(half);
        if (st == PN_OK && strcmp(class_name, "mix") != 0) {
            consume_all(ps);
            pn_warn_at(scene, ps->loc, "texture \"%s\": %s texture approximated by an even mix of its two inputs", name,
                       class_name);
        }
    } else if (strcmp(class_name, "checkerboard") == 0) {
        t.kind = PN_TEXTURE_CHECKERBOARD;
        int dim = 2;
        st = pn_params_int(ps, "dimension", 2, &dim, err);
        if (st == PN_OK && dim != 2) {
            if (dim != 3) {
                snprintf(msg, sizeof msg, "checkerboard texture \"%s\": dimension %d (expected 2 or 3)", name, dim);
                return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, msg);
            }
            pn_warn_at(scene, ps->loc, "texture \"%s\": 3D checkerboard approximated by a 2D checkerboard in uv", name);
        }
        if (st == PN_OK) st = pn_params_texref_use(scene, ps, "tex1", f, one, PN_SPECTRUM_UNBOUNDED, &t.a, err);
        if (st == PN_OK) st = pn_params_texref_use(scene, ps, "tex2", f, zero, PN_SPECTRUM_UNBOUNDED, &t.b, err);
    } else if (strcmp(class_name, "bilerp") == 0) {
        const char *corners[] = {"v00", "v01", "v10", "v11"};
        const vec3 defs[] = {zero, one, zero, one};
        vec3 sum = zero;
        for (int i = 0; i < 4 && st == PN_OK; i++) {
            pn_texref r;
            st = pn_params_texref_use(scene, ps, corners[i], f, defs[i], PN_SPECTRUM_UNBOUNDED, &r, err);
            if (st == PN_OK && r.texture < 0) sum = v3_add(sum, r.value);
            if (st == PN_OK && r.texture >= 0) sum = v3_add(sum, half);
        }
        t.kind = PN_TEXTURE_CONSTANT;
        t.value = v3_scale(sum, 0.25f);
        if (st == PN_OK)
            pn_warn_at(scene, ps->loc, "texture \"%s\": bilerp texture approximated by the average of its corners",
                       name);
    } else if (strcmp(class_name, "fbm") == 0 || strcmp(class_name, "wrinkled") == 0 ||
               strcmp(class_name, "windy") == 0 || strcmp(class_name, "marble") == 0 ||
               strcmp(class_name, "ptex") == 0) {
        consume_all(ps);
        t.kind = PN_TEXTURE_CONSTANT;
        t.value = half;
        pn_warn_at(scene, ps->loc, "texture \"%s\": %s texture is not supported; constant 0.5 used instead", name,
                   class_name);
    } else {
        snprintf(msg, sizeof msg, "unknown texture class \"%s\"", class_name);
        return error_at(ps->loc, PN_ERROR_BAD_INPUT, err, msg);
    }
    if (st != PN_OK) return st;

    t.name = pn_strdup(name);
    if (!t.name || !pn_grow_for_append((void **)&scene->textures, scene->texture_count, sizeof *scene->textures)) {
        free(t.name);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory for texture \"%s\"", name);
    }
    scene->textures[scene->texture_count++] = t;
    return PN_OK;
}

/* ---- evaluation --------------------------------------------------------------------------------- */

vec3 pn_texture_eval(const struct pn_scene_s *scene, pn_texref ref, float u, float v) {
    return pn_texture_eval_footprint(scene, ref, u, v, NULL);
}

vec3 pn_texture_eval_footprint(const struct pn_scene_s *scene, pn_texref ref, float u, float v, const float duv[4]) {
    if (ref.texture < 0 || ref.texture >= scene->texture_count) return ref.value;
    const pn_texture *t = &scene->textures[ref.texture];
    float s = t->su * u + t->du, tt = t->sv * v + t->dv;
    vec3 r;
    switch (t->kind) {
    case PN_TEXTURE_CONSTANT: r = t->value; break;
    case PN_TEXTURE_IMAGE: {
        if (t->mipmap < 0 || t->mipmap >= scene->mipmap_count) return v3(0, 0, 0);
        /* The uv mapping's derivatives: (ds/dx, dt/dx, ds/dy, dt/dy); the flip of t keeps them. */
        float dst[4] = {0, 0, 0, 0};
        if (duv) {
            dst[0] = t->su * duv[0];
            dst[1] = t->sv * duv[1];
            dst[2] = t->su * duv[2];
            dst[3] = t->sv * duv[3];
        }
        r = pn_mipmap_lookup(&scene->mipmaps[t->mipmap], t->filter, s, 1.0f - tt, dst);
        if (t->is_float) {
            /* pbrt-v4 MIPMap: the channel average for bilinear / trilinear lookups, the first
             * channel for point and EWA lookups; the one value is then scaled and inverted. */
            float f = t->float_first_channel ? r.x : (r.x + r.y + r.z) * (1.0f / 3.0f);
            r = v3(f, f, f);
        }
        r = v3_scale(r, t->scale);
        if (t->invert) r = v3_sub(v3(1, 1, 1), r);
        r = v3_max(r, v3(0, 0, 0));
        break;
    }
    case PN_TEXTURE_SCALE:
        r = v3_mul(pn_texture_eval_footprint(scene, t->a, u, v, duv),
                   pn_texture_eval_footprint(scene, t->b, u, v, duv));
        break;
    case PN_TEXTURE_MIX: {
        float amt = pn_texture_eval_footprint(scene, t->amount, u, v, duv).x;
        vec3 a = amt != 1.0f ? pn_texture_eval_footprint(scene, t->a, u, v, duv) : v3(0, 0, 0);
        vec3 b = amt != 0.0f ? pn_texture_eval_footprint(scene, t->b, u, v, duv) : v3(0, 0, 0);
        r = v3_add(v3_scale(a, 1.0f - amt), v3_scale(b, amt));
        break;
    }
    case PN_TEXTURE_CHECKERBOARD: {
        double cell = floor((double)s) + floor((double)tt);
        bool even = fmod(fabs(cell), 2.0) < 0.5;
        r = pn_texture_eval_footprint(scene, even ? t->a : t->b, u, v, duv);
        break;
    }
    default: r = v3(0, 0, 0); break;
    }
    return r;
}
