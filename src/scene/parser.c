/* parser.c — reads a pbrt-v4 scene description (with its Includes and PLY meshes) into a
 * pn_scene_s: graphics state and transforms, camera and film, materials, lights and shapes.
 *
 * The semantics follow pbrt-v4's file format (pbrt.org/fileformat-v4): the current transform
 * matrix (CTM) post-multiplies every transform directive; Camera records camera_from_world = CTM;
 * WorldBegin resets the CTM; AttributeBegin/End save and restore the graphics state; shapes of an
 * ObjectBegin block are stored in the space given by their own CTM and placed by the CTM at each
 * ObjectInstance. Names that pbrt-v4 resolves after parsing (named materials used before they are
 * defined, instances of objects defined later) are resolved here at the end too.
 */
#include "core/context.h"
#include "scene/build.h"
#include "scene/parser_internal.h"
#include "scene/photometry.h"
#include "scene/ply.h"
#include "scene/scene.h"
#include "scene/tokenizer.h"
#include "spectral/transport.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#define PN_MAX_INCLUDE_DEPTH 64
#define PN_DISK_SEGMENTS 64
#define PN_CYLINDER_SEGMENTS 64
#define PN_PI_D 3.14159265358979323846

/* ---- parser state ------------------------------------------------------------------------ */

enum { PN_ATTR_SHAPE = 0, PN_ATTR_LIGHT, PN_ATTR_MATERIAL, PN_ATTR_MEDIUM, PN_ATTR_TEXTURE, PN_ATTR_TARGETS };

static const char *const pn_attr_target_names[PN_ATTR_TARGETS] = {"shape", "light", "material", "medium", "texture"};

/* What AttributeBegin saves and AttributeEnd restores. */
typedef struct pn_gstate {
    mat4 ctm[2];  /* transforms at the shutter's start and end (pbrt's motion blur) */
    int active;   /* which of ctm[] the transform directives change: bit 0 start, bit 1 end */
    int material; /* -1: the default material; >= 0: index; <= -2: pending named material */
    bool area_light_on;
    pn_area_light_desc area_light;
    pn_srcloc area_light_loc;
    bool reverse_orientation;
    int attr_count; /* Attribute defaults in effect: the first attr_count records */
} pn_gstate;

typedef struct pn_pushed_state {
    pn_gstate gs;
    char kind; /* 'a' AttributeBegin, 't' TransformBegin, 'o' ObjectBegin */
    pn_srcloc loc;
} pn_pushed_state;

typedef struct pn_attr_record {
    int target;
    pn_params params;
} pn_attr_record;

typedef struct pn_named_transform {
    char *name;
    mat4 ctm[2];
} pn_named_transform;

typedef struct pn_pending_instance {
    char *name;
    pn_srcloc loc;
    mat4 world_from_object;
} pn_pending_instance;

typedef struct pn_pending_material {
    char *name;
    pn_srcloc loc;
} pn_pending_material;

typedef struct pn_open_file {
    pn_tokenizer tz;
} pn_open_file;

typedef struct pn_parser {
    struct pn_scene_s *scene;
    pn_err *err;

    pn_open_file files[PN_MAX_INCLUDE_DEPTH + 1];
    int depth;
    char **strings; /* file paths and folders; they outlive the tokens that point at them */
    int string_count;
    /* pbrt-v4's search directory: the folder of the top-level scene file. Every relative path
     * (Include, Import, PLY meshes, textures, spectra, light images) resolves against it, in
     * included files too (parser.cpp sets it for the files on the command line only). */
    const char *search_dir;

    pn_gstate gs;
    pn_pushed_state *stack;
    int stack_count, stack_cap;
    pn_attr_record *attrs;
    int attr_count, attr_cap;
    pn_named_transform *named;
    int named_count;
    pn_pending_instance *instances;
    int instance_count;
    pn_pending_material *pending_materials;
    int pending_material_count;

    bool in_world;
    int current_object; /* -1 outside ObjectBegin/End */
    int default_material;

    bool screen_window_given;
    double frame_aspect; /* 0 = from the film resolution */
    bool camera_given;
    pn_srcloc camera_loc, film_loc; /* of the Camera / Film directives (valid while parsing) */
    bool crop_given;                /* Film "cropwindow" (wins over "pixelbounds", as in pbrt) */

    vec3 bounds_lo, bounds_hi;

    uint64_t degenerate_triangles;
    int degenerate_shapes;
    pn_srcloc degenerate_first; /* valid while parsing only */

    /* warnings given once per scene */
    bool warned_motion, warned_media, warned_displacement, warned_object_light, warned_curve, warned_cylinder,
        warned_world_end, warned_transform_times, warned_loop;
} pn_parser;

/* ---- small helpers ----------------------------------------------------------------------- */

static pn_status out_of_memory(pn_parser *p) {
    return pn_err_set(p->err, PN_ERROR_OUT_OF_MEMORY, "out of memory while parsing the scene");
}

static const char *keep_string(pn_parser *p, char *s) {
    if (!s) return NULL;
    if (!pn_grow_for_append((void **)&p->strings, p->string_count, sizeof *p->strings)) {
        free(s);
        return NULL;
    }
    p->strings[p->string_count++] = s;
    return s;
}

static char *dir_of(const char *path) {
    const char *slash = strrchr(path, '/');
    if (!slash) return strdup("");
    if (slash == path) return strdup("/");
    size_t n = (size_t)(slash - path);
    char *d = malloc(n + 1);
    if (!d) return NULL;
    memcpy(d, path, n);
    d[n] = '\0';
    return d;
}

static pn_tokenizer *cur(pn_parser *p) {
    return &p->files[p->depth - 1].tz;
}
static const char *search_dir(const pn_parser *p) {
    return p->search_dir;
}

static bool mat4_equal(const mat4 *a, const mat4 *b) {
    return memcmp(a, b, sizeof *a) == 0;
}

static void warn_motion_once(pn_parser *p, const pn_srcloc *loc) {
    if (p->warned_motion || mat4_equal(&p->gs.ctm[0], &p->gs.ctm[1])) return;
    p->warned_motion = true;
    pn_scene_warn(p->scene,
                  "%s:%d:%d: motion blur (ActiveTransform) is not supported; the transform at "
                  "the start of the shutter is used",
                  loc->file, loc->line, loc->column);
}

static void grow_bounds(pn_parser *p, vec3 lo, vec3 hi) {
    p->bounds_lo = v3_min(p->bounds_lo, lo);
    p->bounds_hi = v3_max(p->bounds_hi, hi);
}

/* ---- warnings ---------------------------------------------------------------------------- */

void pn_scene_warn(struct pn_scene_s *scene, const char *fmt, ...) {
    if (!scene) return;
    va_list ap;
    va_start(ap, fmt);
    pn_warnv(scene->ctx, &scene->warnings, fmt, ap);
    va_end(ap);
}

/* ---- reading directive arguments --------------------------------------------------------- */

static pn_status read_numbers(pn_parser *p, const pn_token *d, int n, double *out) {
    pn_tokenizer *tz = cur(p);
    pn_token t;
    pn_status st = pn_tokenizer_peek(tz, &t, p->err);
    if (st != PN_OK) return st;
    bool bracket = t.kind == PN_TOKEN_LBRACKET;
    if (bracket) pn_tokenizer_next(tz, &t, p->err);
    for (int i = 0; i < n; i++) {
        st = pn_tokenizer_peek(tz, &t, p->err);
        if (st != PN_OK) return st;
        if (!pn_token_is_numeric(&t)) {
            if (bracket && t.kind == PN_TOKEN_EOF)
                return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "the file ends inside the [ ] list of %.*s",
                                    (int)d->len, d->text);
            return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "%.*s needs %d numbers, found %d", (int)d->len,
                                d->text, n, i);
        }
        pn_tokenizer_next(tz, &t, p->err);
        st = pn_token_number(&t, &out[i], p->err);
        if (st != PN_OK) return st;
    }
    if (bracket) {
        st = pn_tokenizer_next(tz, &t, p->err);
        if (st != PN_OK) return st;
        if (t.kind != PN_TOKEN_RBRACKET) {
            if (t.kind == PN_TOKEN_EOF)
                return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "the file ends inside the [ ] list of %.*s",
                                    (int)d->len, d->text);
            return pn_loc_error(&t.loc, PN_ERROR_BAD_INPUT, p->err, "%.*s needs exactly %d numbers; expected ']'",
                                (int)d->len, d->text, n);
        }
    }
    return PN_OK;
}

static pn_status read_string(pn_parser *p, const pn_token *d, const char *what, pn_token *out) {
    pn_status st = pn_tokenizer_next(cur(p), out, p->err);
    if (st != PN_OK) return st;
    if (out->kind == PN_TOKEN_STRING) return PN_OK;
    const pn_srcloc *loc = out->kind == PN_TOKEN_EOF ? &d->loc : &out->loc;
    return pn_loc_error(loc, PN_ERROR_BAD_INPUT, p->err, "%.*s expects %s as a quoted string", (int)d->len, d->text,
                        what);
}

static void params_init(pn_parser *p, const pn_token *d, pn_params *ps) {
    memset(ps, 0, sizeof *ps);
    ps->base_dir = search_dir(p);
    ps->loc = d->loc;
}

static pn_status read_params(pn_parser *p, const pn_token *d, pn_params *ps) {
    params_init(p, d, ps);
    return pn_params_parse(cur(p), ps, p->err);
}

/* Appends the defaults of Attribute "target" in effect that the directive did not give. */
static pn_status add_attr_defaults(pn_parser *p, int target, pn_params *ps) {
    for (int i = p->gs.attr_count - 1; i >= 0; i--) {
        const pn_attr_record *r = &p->attrs[i];
        if (r->target != target) continue;
        for (int j = r->params.count - 1; j >= 0; j--) {
            const pn_param *q = &r->params.items[j];
            bool present = false;
            for (int k = 0; k < ps->count && !present; k++) present = strcmp(ps->items[k].name, q->name) == 0;
            if (present) continue;
            pn_status st = pn_params_append_copy(ps, q, p->err);
            if (st != PN_OK) return st;
        }
    }
    return PN_OK;
}

static void warn_unused(pn_parser *p, const pn_params *ps, int own_count, const pn_token *d, const char *type) {
    for (int i = 0; i < own_count && i < ps->count; i++) {
        const pn_param *q = &ps->items[i];
        if (q->used) continue;
        if (type)
            pn_scene_warn(p->scene, "%s:%d:%d: unused parameter \"%s %s\" for %.*s \"%s\"", q->loc.file, q->loc.line,
                          q->loc.column, pn_param_type_name(q->type), q->name, (int)d->len, d->text, type);
        else
            pn_scene_warn(p->scene, "%s:%d:%d: unused parameter \"%s %s\" for %.*s", q->loc.file, q->loc.line,
                          q->loc.column, pn_param_type_name(q->type), q->name, (int)d->len, d->text);
    }
}

/* ---- transforms -------------------------------------------------------------------------- */

static void apply_transform(pn_parser *p, mat4 t) {
    for (int i = 0; i < 2; i++)
        if (p->gs.active & (1 << i)) p->gs.ctm[i] = mat4_mul(p->gs.ctm[i], t);
}

static pn_status d_identity(pn_parser *p, const pn_token *d) {
    (void)d;
    for (int i = 0; i < 2; i++)
        if (p->gs.active & (1 << i)) p->gs.ctm[i] = mat4_identity();
    return PN_OK;
}

static pn_status d_translate(pn_parser *p, const pn_token *d) {
    double v[3];
    pn_status st = read_numbers(p, d, 3, v);
    if (st == PN_OK) apply_transform(p, mat4_translate(v[0], v[1], v[2]));
    return st;
}

static pn_status d_scale(pn_parser *p, const pn_token *d) {
    double v[3];
    pn_status st = read_numbers(p, d, 3, v);
    if (st == PN_OK) apply_transform(p, mat4_scale(v[0], v[1], v[2]));
    return st;
}

static pn_status d_rotate(pn_parser *p, const pn_token *d) {
    double v[4];
    pn_status st = read_numbers(p, d, 4, v);
    if (st != PN_OK) return st;
    if (v[1] == 0.0 && v[2] == 0.0 && v[3] == 0.0)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "Rotate has a zero rotation axis");
    apply_transform(p, mat4_rotate(v[0], v[1], v[2], v[3]));
    return PN_OK;
}

static pn_status d_look_at(pn_parser *p, const pn_token *d) {
    double v[9];
    pn_status st = read_numbers(p, d, 9, v);
    if (st != PN_OK) return st;
    mat4 m;
    if (!mat4_look_at(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8], &m))
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err,
                            "LookAt is degenerate: the eye equals the look-at point, or the up vector is zero "
                            "or parallel to the viewing direction");
    apply_transform(p, m);
    return PN_OK;
}

/* pbrt lists the 16 numbers column by column (the translation is in elements 12..14). */
static pn_status read_matrix(pn_parser *p, const pn_token *d, mat4 *m) {
    double v[16];
    pn_status st = read_numbers(p, d, 16, v);
    if (st != PN_OK) return st;
    for (int r = 0; r < 4; r++)
        for (int c = 0; c < 4; c++) m->m[r][c] = v[c * 4 + r];
    return PN_OK;
}

static pn_status d_transform(pn_parser *p, const pn_token *d) {
    mat4 m;
    pn_status st = read_matrix(p, d, &m);
    if (st != PN_OK) return st;
    for (int i = 0; i < 2; i++)
        if (p->gs.active & (1 << i)) p->gs.ctm[i] = m;
    return PN_OK;
}

static pn_status d_concat_transform(pn_parser *p, const pn_token *d) {
    mat4 m;
    pn_status st = read_matrix(p, d, &m);
    if (st == PN_OK) apply_transform(p, m);
    return st;
}

static pn_named_transform *find_named(pn_parser *p, const char *name) {
    for (int i = p->named_count - 1; i >= 0; i--)
        if (strcmp(p->named[i].name, name) == 0) return &p->named[i];
    return NULL;
}

static pn_status set_named(pn_parser *p, const char *name, const mat4 ctm[2]) {
    pn_named_transform *n = find_named(p, name);
    if (!n) {
        char *copy = strdup(name);
        if (!copy || !pn_grow_for_append((void **)&p->named, p->named_count, sizeof *p->named)) {
            free(copy);
            return out_of_memory(p);
        }
        n = &p->named[p->named_count++];
        n->name = copy;
    }
    n->ctm[0] = ctm[0];
    n->ctm[1] = ctm[1];
    return PN_OK;
}

static pn_status d_coordinate_system(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "a name", &name);
    if (st != PN_OK) return st;
    return set_named(p, name.text, p->gs.ctm);
}

static pn_status d_coord_sys_transform(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "a name", &name);
    if (st != PN_OK) return st;
    const pn_named_transform *n = find_named(p, name.text);
    if (!n) {
        pn_scene_warn(p->scene, "%s:%d:%d: unknown coordinate system \"%s\"; the transform is unchanged", name.loc.file,
                      name.loc.line, name.loc.column, name.text);
        return PN_OK;
    }
    p->gs.ctm[0] = n->ctm[0];
    p->gs.ctm[1] = n->ctm[1];
    return PN_OK;
}

static pn_status d_active_transform(pn_parser *p, const pn_token *d) {
    pn_token t;
    pn_status st = pn_tokenizer_next(cur(p), &t, p->err);
    if (st != PN_OK) return st;
    if (pn_token_is(&t, "StartTime"))
        p->gs.active = 1;
    else if (pn_token_is(&t, "EndTime"))
        p->gs.active = 2;
    else if (pn_token_is(&t, "All"))
        p->gs.active = 3;
    else
        return pn_loc_error(t.kind == PN_TOKEN_EOF ? &d->loc : &t.loc, PN_ERROR_BAD_INPUT, p->err,
                            "ActiveTransform expects StartTime, EndTime or All");
    return PN_OK;
}

static pn_status d_transform_times(pn_parser *p, const pn_token *d) {
    double v[2];
    pn_status st = read_numbers(p, d, 2, v);
    if (st == PN_OK && !p->warned_transform_times) {
        p->warned_transform_times = true;
        pn_scene_warn(p->scene, "%s:%d:%d: TransformTimes ignored (no motion blur)", d->loc.file, d->loc.line,
                      d->loc.column);
    }
    return st;
}

/* ---- graphics state stack ---------------------------------------------------------------- */

static pn_status push_state(pn_parser *p, char kind, const pn_srcloc *loc) {
    if (p->stack_count == p->stack_cap) {
        int ncap = p->stack_cap ? p->stack_cap * 2 : 16;
        pn_pushed_state *s = realloc(p->stack, (size_t)ncap * sizeof *s);
        if (!s) return out_of_memory(p);
        p->stack = s;
        p->stack_cap = ncap;
    }
    p->stack[p->stack_count].gs = p->gs;
    p->stack[p->stack_count].kind = kind;
    p->stack[p->stack_count].loc = *loc;
    p->stack_count++;
    return PN_OK;
}

static const char *begin_name(char kind) {
    return kind == 'a' ? "AttributeBegin" : kind == 't' ? "TransformBegin" : "ObjectBegin";
}

static void truncate_attrs(pn_parser *p, int count) {
    while (p->attr_count > count) pn_params_free(&p->attrs[--p->attr_count].params);
}

static pn_status pop_state(pn_parser *p, const pn_token *d, char kind) {
    const char *end_name = kind == 'a' ? "AttributeEnd" : kind == 't' ? "TransformEnd" : "ObjectEnd";
    if (p->stack_count == 0)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "%s without a matching %s", end_name,
                            begin_name(kind));
    const pn_pushed_state *top = &p->stack[p->stack_count - 1];
    if (top->kind != kind)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "%s does not match the %s at %s:%d:%d", end_name,
                            begin_name(top->kind), top->loc.file, top->loc.line, top->loc.column);
    if (kind == 't') {
        p->gs.ctm[0] = top->gs.ctm[0];
        p->gs.ctm[1] = top->gs.ctm[1];
        p->gs.active = top->gs.active;
    } else {
        p->gs = top->gs;
        truncate_attrs(p, p->gs.attr_count);
    }
    p->stack_count--;
    return PN_OK;
}

static pn_status d_attribute_begin(pn_parser *p, const pn_token *d) {
    return push_state(p, 'a', &d->loc);
}
static pn_status d_attribute_end(pn_parser *p, const pn_token *d) {
    return pop_state(p, d, 'a');
}
static pn_status d_transform_begin(pn_parser *p, const pn_token *d) {
    return push_state(p, 't', &d->loc);
}
static pn_status d_transform_end(pn_parser *p, const pn_token *d) {
    return pop_state(p, d, 't');
}

static pn_status d_attribute(pn_parser *p, const pn_token *d) {
    pn_token target;
    pn_status st = read_string(p, d, "a target (shape, light, material, medium or texture)", &target);
    if (st != PN_OK) return st;
    int t = -1;
    for (int i = 0; i < PN_ATTR_TARGETS; i++)
        if (strcmp(target.text, pn_attr_target_names[i]) == 0) t = i;
    if (t < 0)
        return pn_loc_error(&target.loc, PN_ERROR_BAD_INPUT, p->err,
                            "unknown Attribute target \"%s\" (expected shape, light, material, medium or texture)",
                            target.text);
    if (p->attr_count == p->attr_cap) {
        int ncap = p->attr_cap ? p->attr_cap * 2 : 8;
        pn_attr_record *a = realloc(p->attrs, (size_t)ncap * sizeof *a);
        if (!a) return out_of_memory(p);
        p->attrs = a;
        p->attr_cap = ncap;
    }
    pn_attr_record *r = &p->attrs[p->attr_count++];
    r->target = t;
    st = read_params(p, d, &r->params);
    p->gs.attr_count = p->attr_count;
    if (st != PN_OK) return st;
    if (t == PN_ATTR_MEDIUM && !p->warned_media) {
        p->warned_media = true;
        pn_scene_warn(p->scene, "%s:%d:%d: participating media are ignored", d->loc.file, d->loc.line, d->loc.column);
    }
    return PN_OK;
}

static pn_status d_reverse_orientation(pn_parser *p, const pn_token *d) {
    (void)d;
    p->gs.reverse_orientation = !p->gs.reverse_orientation;
    return PN_OK;
}

/* ---- options block ----------------------------------------------------------------------- */

static pn_status d_option(pn_parser *p, const pn_token *d) {
    pn_params ps;
    pn_status st = read_params(p, d, &ps);
    for (int i = 0; st == PN_OK && i < ps.count; i++)
        pn_scene_warn(p->scene, "%s:%d:%d: Option \"%s %s\" ignored", ps.items[i].loc.file, ps.items[i].loc.line,
                      ps.items[i].loc.column, pn_param_type_name(ps.items[i].type), ps.items[i].name);
    pn_params_free(&ps);
    return st;
}

static pn_status d_color_space(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "a color space name", &name);
    if (st != PN_OK) return st;
    if (strcmp(name.text, "srgb") != 0)
        pn_scene_warn(p->scene, "%s:%d:%d: ColorSpace \"%s\" is not supported; RGB values are taken as sRGB",
                      name.loc.file, name.loc.line, name.loc.column, name.text);
    return PN_OK;
}

static pn_status replace_string(pn_parser *p, char **dst, const char *value) {
    char *c = strdup(value);
    if (!c) return out_of_memory(p);
    free(*dst);
    *dst = c;
    return PN_OK;
}

/* Camera "perspective" | "orthographic" | "spherical" (cameras.cpp). "realistic" simulates a
 * lens system from a lens file, which penumbra does not: it stops with an error that names the
 * thin-lens substitute instead of rendering a different image. */
static pn_status d_camera(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the camera type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    if (st != PN_OK) goto done;
    pn_camera_def *cam = &p->scene->camera;
    pn_camera_projection projection;
    if (strcmp(type.text, "perspective") == 0) {
        projection = PN_PROJECTION_PERSPECTIVE;
    } else if (strcmp(type.text, "orthographic") == 0) {
        projection = PN_PROJECTION_ORTHOGRAPHIC;
    } else if (strcmp(type.text, "spherical") == 0) {
        const char *mapping;
        if ((st = pn_params_string(&ps, "mapping", "equalarea", &mapping, p->err)) != PN_OK) goto done;
        if (strcmp(mapping, "equalarea") == 0) {
            projection = PN_PROJECTION_EQUAL_AREA;
        } else if (strcmp(mapping, "equirectangular") == 0) {
            projection = PN_PROJECTION_EQUIRECTANGULAR;
        } else {
            st = pn_param_error(pn_params_find(&ps, "mapping"), p->err,
                                "unknown \"mapping\" \"%s\" for the spherical camera (pbrt-v4 knows \"equalarea\" "
                                "and \"equirectangular\")",
                                mapping);
            goto done;
        }
    } else if (strcmp(type.text, "realistic") == 0) {
        st = pn_loc_error(&type.loc, PN_ERROR_UNSUPPORTED, p->err,
                          "Camera \"realistic\" (a lens system read from \"lensfile\") is not supported; use "
                          "Camera \"perspective\" with \"lensradius\" and \"focaldistance\" (a thin lens) instead");
        goto done;
    } else {
        st = pn_loc_error(&type.loc, PN_ERROR_UNSUPPORTED, p->err,
                          "Camera \"%s\" is not supported (penumbra renders \"perspective\", \"orthographic\" and "
                          "\"spherical\" cameras)",
                          type.text);
        goto done;
    }
    mat4 inv;
    if (!mat4_inverse(p->gs.ctm[0], &inv)) {
        st = pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "the camera transform is singular");
        goto done;
    }
    warn_motion_once(p, &d->loc);
    cam->camera_from_world = p->gs.ctm[0];
    cam->world_from_camera = inv;
    cam->projection = projection;
    mat4 both[2] = {inv, inv};
    if (!mat4_inverse(p->gs.ctm[1], &both[1])) both[1] = inv;
    st = set_named(p, "camera", both);
    if (st != PN_OK) goto done;

    double fov = 90.0, lens, focal, aspect, open, close;
    if (projection == PN_PROJECTION_PERSPECTIVE && (st = pn_params_float(&ps, "fov", 90.0, &fov, p->err)) != PN_OK)
        goto done;
    /* pbrt's spherical camera reads these four and ignores them; so does penumbra, silently. */
    if ((st = pn_params_float(&ps, "lensradius", 0.0, &lens, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "focaldistance", 1e6, &focal, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "frameaspectratio", 0.0, &aspect, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "shutteropen", 0.0, &open, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "shutterclose", 1.0, &close, p->err)) != PN_OK) goto done;
    /* an orthographic or spherical camera has no fov: a given one is reported as unused */
    const pn_param *fp = projection == PN_PROJECTION_PERSPECTIVE ? pn_params_find(&ps, "fov") : NULL;
    if (fp && !(fov > 0.0 && fov < 180.0)) {
        st = pn_param_error(fp, p->err, "\"fov\" must be between 0 and 180 degrees, not %g", fov);
        goto done;
    }
    const double *sw;
    int swn;
    if ((st = pn_params_array(&ps, "screenwindow", PN_PT_FLOAT, 0, &sw, &swn, p->err)) != PN_OK) goto done;
    if (sw) {
        if (swn != 4) {
            st = pn_param_error(pn_params_find(&ps, "screenwindow"), p->err,
                                "\"screenwindow\" needs 4 values (xmin xmax ymin ymax), found %d", swn);
            goto done;
        }
        for (int i = 0; i < 4; i++) cam->screen_window[i] = (float)sw[i];
        p->screen_window_given = true;
    }
    cam->fov_deg = (float)fov;
    cam->lens_radius =
        projection == PN_PROJECTION_EQUAL_AREA || projection == PN_PROJECTION_EQUIRECTANGULAR ? 0.0f : (float)lens;
    cam->focal_distance = (float)focal;
    cam->shutter_open = (float)open;
    cam->shutter_close = (float)close;
    p->frame_aspect = aspect > 0.0 ? aspect : 0.0;
    p->camera_given = true;
    p->camera_loc = d->loc;
    warn_unused(p, &ps, ps.count, d, type.text);
done:
    pn_params_free(&ps);
    return st;
}

/* Film "rgb" (also "gbuffer" and "spectral", read as rgb): resolution, crop window or pixel
 * bounds, and the parameters of pbrt-v4's PixelSensor and RGBFilm that scale the image (iso,
 * whitebalance, sensor, maxcomponentvalue; film.cpp). */
static pn_status d_film(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the film type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    if (st != PN_OK) goto done;
    if (strcmp(type.text, "rgb") != 0 && strcmp(type.text, "gbuffer") != 0 && strcmp(type.text, "spectral") != 0)
        pn_scene_warn(p->scene, "%s:%d:%d: Film \"%s\" is not supported; treated as \"rgb\"", type.loc.file,
                      type.loc.line, type.loc.column, type.text);
    pn_camera_def *cam = &p->scene->camera;
    int w, h;
    if ((st = pn_params_int(&ps, "xresolution", 1280, &w, p->err)) != PN_OK) goto done;
    if ((st = pn_params_int(&ps, "yresolution", 720, &h, p->err)) != PN_OK) goto done;
    if (w <= 0 || h <= 0 || w > 65536 || h > 65536) {
        const pn_param *bad = pn_params_find(&ps, w <= 0 || w > 65536 ? "xresolution" : "yresolution");
        st = pn_param_error(bad, p->err, "the film resolution must be between 1 and 65536, not %d",
                            w <= 0 || w > 65536 ? w : h);
        goto done;
    }
    cam->width = w;
    cam->height = h;
    const double *cw;
    int cwn;
    if ((st = pn_params_array(&ps, "cropwindow", PN_PT_FLOAT, 0, &cw, &cwn, p->err)) != PN_OK) goto done;
    const double *pbv;
    int pbn;
    if ((st = pn_params_array(&ps, "pixelbounds", PN_PT_INTEGER, 0, &pbv, &pbn, p->err)) != PN_OK) goto done;
    const pn_param *cp = pn_params_find(&ps, "cropwindow"), *pb = pn_params_find(&ps, "pixelbounds");
    cam->pixel_bounds_given = false;
    p->crop_given = false;
    if (cw) {
        if (cwn != 4) {
            st = pn_param_error(cp, p->err, "\"cropwindow\" needs 4 values (x0 x1 y0 y1), found %d", cwn);
            goto done;
        }
        /* pbrt sorts each pair, then clamps to [0, 1]; the window's pixels are ceil(res * crop). */
        float c[4];
        for (int k = 0; k < 2; k++) {
            c[2 * k] = (float)fmin(1.0, fmax(0.0, fmin(cw[2 * k], cw[2 * k + 1])));
            c[2 * k + 1] = (float)fmin(1.0, fmax(0.0, fmax(cw[2 * k], cw[2 * k + 1])));
        }
        if (!(ceilf((float)w * c[0]) < ceilf((float)w * c[1])) || !(ceilf((float)h * c[2]) < ceilf((float)h * c[3]))) {
            st = pn_param_error(cp, p->err, "\"cropwindow\" [%g %g %g %g] covers no pixel of the %dx%d film", cw[0],
                                cw[1], cw[2], cw[3], w, h);
            goto done;
        }
        memcpy(cam->crop, c, sizeof c);
        p->crop_given = true;
        if (pb)
            pn_warn_at(p->scene, pb->loc,
                       "both \"pixelbounds\" and \"cropwindow\" are given; the crop window is used "
                       "(as pbrt-v4 does)");
    } else if (pb) {
        if (pbn != 4) {
            st = pn_param_error(pb, p->err, "\"pixelbounds\" needs 4 integers (x0 x1 y0 y1), found %d", pbn);
            goto done;
        }
        /* pbrt: the bounds of the points (x0, y0) and (x1, y1), intersected with the film. */
        double lo[2] = {fmin(pbv[0], pbv[1]), fmin(pbv[2], pbv[3])};
        double hi[2] = {fmax(pbv[0], pbv[1]), fmax(pbv[2], pbv[3])};
        double res[2] = {w, h};
        bool clamped = false;
        int b[4];
        for (int k = 0; k < 2; k++) {
            double l = fmax(lo[k], 0.0), u = fmin(hi[k], res[k]);
            clamped = clamped || l != lo[k] || u != hi[k];
            b[2 * k] = (int)l;
            b[2 * k + 1] = (int)u;
        }
        if (!(b[0] < b[1]) || !(b[2] < b[3])) {
            st = pn_param_error(pb, p->err, "\"pixelbounds\" [%g %g %g %g] covers no pixel of the %dx%d film", pbv[0],
                                pbv[1], pbv[2], pbv[3], w, h);
            goto done;
        }
        if (clamped)
            pn_warn_at(p->scene, pb->loc, "\"pixelbounds\" extends beyond the %dx%d film; clamped to [%d %d %d %d]", w,
                       h, b[0], b[1], b[2], b[3]);
        memcpy(cam->pixel_bounds, b, sizeof b);
        cam->pixel_bounds_given = true;
        cam->crop[0] = (float)b[0] / (float)w;
        cam->crop[1] = (float)b[1] / (float)w;
        cam->crop[2] = (float)b[2] / (float)h;
        cam->crop[3] = (float)b[3] / (float)h;
    }
    const char *filename;
    if ((st = pn_params_string(&ps, "filename", NULL, &filename, p->err)) != PN_OK) goto done;
    if (filename && (st = replace_string(p, &cam->film_filename, filename)) != PN_OK) goto done;
    double iso, wb, maxc;
    const char *sensor;
    if ((st = pn_params_float(&ps, "iso", 100.0, &iso, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "whitebalance", 0.0, &wb, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "maxcomponentvalue", INFINITY, &maxc, p->err)) != PN_OK) goto done;
    if ((st = pn_params_string(&ps, "sensor", "cie1931", &sensor, p->err)) != PN_OK) goto done;
    const pn_param *ip = pn_params_find(&ps, "iso"), *wp = pn_params_find(&ps, "whitebalance");
    const pn_param *mp = pn_params_find(&ps, "maxcomponentvalue");
    if (ip && !(iso > 0.0)) {
        st = pn_param_error(ip, p->err, "\"iso\" must be positive, not %g", iso);
        goto done;
    }
    if (wp && wb != 0.0 && !(wb >= 1667.0 && wb <= 25000.0)) {
        st = pn_param_error(wp, p->err,
                            "\"whitebalance\" must be a colour temperature in 1667..25000 K (or 0 for "
                            "none), not %g",
                            wb);
        goto done;
    }
    if (mp && !(maxc > 0.0)) {
        st = pn_param_error(mp, p->err, "\"maxcomponentvalue\" must be positive, not %g", maxc);
        goto done;
    }
    if (strcmp(sensor, "cie1931") != 0) {
        /* pbrt's named sensors integrate measured camera responses and default to a 6500 K white
         * balance; penumbra has no spectra to integrate, so it keeps the XYZ response. */
        const pn_param *sp = pn_params_find(&ps, "sensor");
        if (wb == 0.0) wb = 6500.0;
        pn_warn_at(p->scene, sp->loc,
                   "\"sensor\" \"%s\" is not supported: the \"cie1931\" (XYZ) response is used, "
                   "white-balanced for %g K",
                   sensor, wb);
    }
    cam->iso = (float)iso;
    cam->white_balance_k = (float)wb;
    cam->max_component_value = isfinite(maxc) ? (float)maxc : 0.0f;
    p->film_loc = d->loc;
    warn_unused(p, &ps, ps.count, d, type.text);
done:
    pn_params_free(&ps);
    return st;
}

static pn_status d_pixel_filter(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the filter type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    if (st != PN_OK) goto done;
    pn_camera_def *cam = &p->scene->camera;
    double def_radius, sigma = 0.5, b = 1.0 / 3.0, c = 1.0 / 3.0;
    pn_filter_kind kind;
    if (strcmp(type.text, "box") == 0) {
        kind = PN_FILTER_BOX;
        def_radius = 0.5;
    } else if (strcmp(type.text, "triangle") == 0) {
        kind = PN_FILTER_TRIANGLE;
        def_radius = 2.0;
    } else if (strcmp(type.text, "gaussian") == 0) {
        kind = PN_FILTER_GAUSSIAN;
        def_radius = 1.5;
    } else if (strcmp(type.text, "mitchell") == 0) {
        kind = PN_FILTER_MITCHELL;
        def_radius = 2.0;
    } else if (strcmp(type.text, "sinc") == 0 || strcmp(type.text, "lanczos") == 0) {
        kind = PN_FILTER_GAUSSIAN;
        def_radius = 4.0;
        pn_params_find(&ps, "tau");
        pn_scene_warn(p->scene,
                      "%s:%d:%d: PixelFilter \"%s\" is not supported; a gaussian filter of the same "
                      "radius is used",
                      type.loc.file, type.loc.line, type.loc.column, type.text);
    } else {
        st = pn_loc_error(&type.loc, PN_ERROR_BAD_INPUT, p->err, "unknown PixelFilter \"%s\"", type.text);
        goto done;
    }
    double rx, ry;
    if ((st = pn_params_float(&ps, "xradius", def_radius, &rx, p->err)) != PN_OK) goto done;
    if ((st = pn_params_float(&ps, "yradius", def_radius, &ry, p->err)) != PN_OK) goto done;
    if (!(rx > 0.0) || !(ry > 0.0)) {
        const pn_param *bad = pn_params_find(&ps, !(rx > 0.0) ? "xradius" : "yradius");
        st = pn_param_error(bad, p->err, "the filter radius must be positive");
        goto done;
    }
    if (kind == PN_FILTER_GAUSSIAN && (st = pn_params_float(&ps, "sigma", 0.5, &sigma, p->err)) != PN_OK) goto done;
    if (kind == PN_FILTER_MITCHELL) {
        if ((st = pn_params_float(&ps, "B", 1.0 / 3.0, &b, p->err)) != PN_OK) goto done;
        if ((st = pn_params_float(&ps, "C", 1.0 / 3.0, &c, p->err)) != PN_OK) goto done;
    }
    cam->filter = kind;
    cam->filter_radius[0] = (float)rx;
    cam->filter_radius[1] = (float)ry;
    cam->gaussian_sigma = (float)sigma;
    cam->mitchell_b = (float)b;
    cam->mitchell_c = (float)c;
    warn_unused(p, &ps, ps.count, d, type.text);
done:
    pn_params_free(&ps);
    return st;
}

/* Sampler: penumbra draws its own (Owen-scrambled Sobol) samples; "pixelsamples" is kept for
 * reports and every other parameter is reported as unused (pbrt-v4 would stop on unused ones). */
static pn_status d_sampler(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the sampler type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int n = 16;
    if (st == PN_OK) st = pn_params_int(&ps, "pixelsamples", 16, &n, p->err);
    if (st == PN_OK) {
        p->scene->camera.pixel_samples = n;
        warn_unused(p, &ps, ps.count, d, type.text);
    }
    pn_params_free(&ps);
    return st;
}

/* Integrator: penumbra's method is chosen on its command line; "maxdepth" sets the VPL
 * integrators' default light-path depth (pn_scene_vpl_depth). The direct-light integrators
 * (reference, ias, contour, contour-mc) compute direct light only, which is pbrt's maxdepth 1;
 * a larger maxdepth is reported so that a comparison with pbrt's image is not made blindly. */
static pn_status d_integrator(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the integrator type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int depth = 5;
    if (st == PN_OK) st = pn_params_int(&ps, "maxdepth", 5, &depth, p->err);
    const pn_param *dp = st == PN_OK ? pn_params_find(&ps, "maxdepth") : NULL;
    if (dp && depth < 0) st = pn_param_error(dp, p->err, "\"maxdepth\" must not be negative, not %d", depth);
    if (st == PN_OK) {
        p->scene->camera.max_depth = depth;
        p->scene->camera.max_depth_given = dp != NULL;
        st = replace_string(p, &p->scene->camera.integrator_name, type.text);
    }
    if (st == PN_OK && dp && depth != 1)
        pn_warn_at(p->scene, dp->loc,
                   "Integrator \"%s\" \"maxdepth\" %d: the VPL integrators (vpl, lightcuts, illumcut) default to "
                   "light paths of %d bounce%s; the direct-light integrators (reference, ias, contour, contour-mc) "
                   "render direct light only, as pbrt does with maxdepth 1",
                   type.text, depth, depth > 0 ? depth - 1 : 0, depth == 2 ? "" : "s");
    if (st == PN_OK) warn_unused(p, &ps, ps.count, d, type.text);
    pn_params_free(&ps);
    return st;
}

/* Accelerator: penumbra always builds Embree's BVH; the parameters are reported as unused. */
static pn_status d_accelerator(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the accelerator type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    if (st == PN_OK) warn_unused(p, &ps, ps.count, d, type.text);
    pn_params_free(&ps);
    return st;
}

static void warn_media_once(pn_parser *p, const pn_srcloc *loc) {
    if (p->warned_media) return;
    p->warned_media = true;
    pn_scene_warn(p->scene, "%s:%d:%d: participating media are ignored", loc->file, loc->line, loc->column);
}

static pn_status d_make_named_medium(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "the medium name", &name);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    pn_params_free(&ps);
    if (st == PN_OK) warn_media_once(p, &d->loc);
    return st;
}

static pn_status d_medium_interface(pn_parser *p, const pn_token *d) {
    pn_token inside, outside;
    pn_status st = read_string(p, d, "the inside medium name", &inside);
    if (st != PN_OK) return st;
    st = pn_tokenizer_peek(cur(p), &outside, p->err);
    if (st != PN_OK) return st;
    /* A second name is optional; a quoted string that looks like "type name" starts a parameter
     * list instead (MediumInterface takes none, but be lenient). */
    if (outside.kind == PN_TOKEN_STRING && !strchr(outside.text, ' ')) pn_tokenizer_next(cur(p), &outside, p->err);
    if (inside.text[0] != '\0' || (outside.kind == PN_TOKEN_STRING && outside.text[0] != '\0'))
        warn_media_once(p, &d->loc);
    return PN_OK;
}

static pn_status d_world_begin(pn_parser *p, const pn_token *d) {
    if (p->in_world) return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "WorldBegin appears twice");
    p->in_world = true;
    p->gs.ctm[0] = p->gs.ctm[1] = mat4_identity();
    p->gs.active = 3;
    return set_named(p, "world", p->gs.ctm);
}

static pn_status d_world_end(pn_parser *p, const pn_token *d) {
    if (!p->warned_world_end) {
        p->warned_world_end = true;
        pn_scene_warn(p->scene, "%s:%d:%d: WorldEnd is a pbrt-v3 directive; ignored", d->loc.file, d->loc.line,
                      d->loc.column);
    }
    return PN_OK;
}

/* ---- materials, textures, lights --------------------------------------------------------- */

static pn_status d_texture(pn_parser *p, const pn_token *d) {
    pn_token name, type, cls;
    pn_status st = read_string(p, d, "the texture name", &name);
    if (st == PN_OK) st = read_string(p, d, "the texture type (\"float\" or \"spectrum\")", &type);
    if (st == PN_OK) st = read_string(p, d, "the texture class", &cls);
    if (st != PN_OK) return st;
    if (strcmp(type.text, "float") != 0 && strcmp(type.text, "spectrum") != 0 && strcmp(type.text, "color") != 0)
        return pn_loc_error(&type.loc, PN_ERROR_BAD_INPUT, p->err,
                            "texture type \"%s\" is neither \"float\" nor \"spectrum\"", type.text);
    const char *value_type = strcmp(type.text, "float") == 0 ? "float" : "spectrum";
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count;
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_TEXTURE, &ps);
    if (st == PN_OK) st = pn_texture_from_pbrt(p->scene, name.text, value_type, cls.text, &ps, p->err);
    if (st == PN_OK) warn_unused(p, &ps, own, d, cls.text);
    pn_params_free(&ps);
    return st;
}

static pn_status d_material(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the material type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count, index = -1;
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_MATERIAL, &ps);
    if (st == PN_OK) st = pn_material_from_pbrt(p->scene, type.text, "", &ps, &index, p->err);
    if (st == PN_OK) {
        p->gs.material = index;
        warn_unused(p, &ps, own, d, type.text);
    }
    pn_params_free(&ps);
    return st;
}

static pn_status d_make_named_material(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "the material name", &name);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count, index = -1;
    const char *type = NULL;
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_MATERIAL, &ps);
    if (st == PN_OK) st = pn_params_string(&ps, "type", NULL, &type, p->err);
    if (st == PN_OK && !type)
        st = pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err,
                          "MakeNamedMaterial \"%s\" has no \"string type\" parameter", name.text);
    if (st == PN_OK) st = pn_material_from_pbrt(p->scene, type, name.text, &ps, &index, p->err);
    if (st == PN_OK) warn_unused(p, &ps, own, d, name.text);
    pn_params_free(&ps);
    return st;
}

static pn_status d_named_material(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "the material name", &name);
    if (st != PN_OK) return st;
    int index = pn_scene_find_material(p->scene, name.text);
    if (index >= 0) {
        p->gs.material = index;
        return PN_OK;
    }
    /* pbrt-v4 resolves names after parsing, so a material may be defined later in the file. */
    char *copy = strdup(name.text);
    if (!copy ||
        !pn_grow_for_append((void **)&p->pending_materials, p->pending_material_count, sizeof *p->pending_materials)) {
        free(copy);
        return out_of_memory(p);
    }
    p->pending_materials[p->pending_material_count] = (pn_pending_material){copy, name.loc};
    p->gs.material = -2 - p->pending_material_count;
    p->pending_material_count++;
    return PN_OK;
}

static pn_status d_light_source(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the light type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count;
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_LIGHT, &ps);
    if (st == PN_OK) {
        warn_motion_once(p, &d->loc);
        st = pn_light_from_pbrt(p->scene, type.text, &ps, &p->gs.ctm[0], p->err);
    }
    if (st == PN_OK) warn_unused(p, &ps, own, d, type.text);
    pn_params_free(&ps);
    return st;
}

static pn_status d_area_light_source(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the area light type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count;
    pn_area_light_desc desc;
    memset(&desc, 0, sizeof desc);
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_LIGHT, &ps);
    if (st == PN_OK) st = pn_area_light_from_pbrt(p->scene, type.text, &ps, &desc, p->err);
    if (st == PN_OK) {
        p->gs.area_light_on = true;
        p->gs.area_light = desc;
        p->gs.area_light_loc = d->loc;
        warn_unused(p, &ps, own, d, type.text);
    }
    pn_params_free(&ps);
    return st;
}

/* ---- objects and instances --------------------------------------------------------------- */

static pn_status d_object_begin(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "the object name", &name);
    if (st != PN_OK) return st;
    struct pn_scene_s *s = p->scene;
    if (p->current_object >= 0)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err,
                            "ObjectBegin \"%s\" inside the definition of object \"%s\" (objects cannot nest)",
                            name.text, s->objects[p->current_object].name);
    for (int i = 0; i < s->object_count; i++)
        if (strcmp(s->objects[i].name, name.text) == 0)
            return pn_loc_error(&name.loc, PN_ERROR_BAD_INPUT, p->err, "object \"%s\" is defined twice", name.text);
    st = push_state(p, 'o', &d->loc);
    if (st != PN_OK) return st;
    char *copy = strdup(name.text);
    if (!copy || !pn_grow_for_append((void **)&s->objects, s->object_count, sizeof *s->objects)) {
        free(copy);
        return out_of_memory(p);
    }
    pn_object *o = &s->objects[s->object_count];
    memset(o, 0, sizeof *o);
    o->name = copy;
    o->first_mesh = s->mesh_count;
    o->first_sphere = s->sphere_count;
    p->current_object = s->object_count++;
    return PN_OK;
}

static pn_status d_object_end(pn_parser *p, const pn_token *d) {
    if (p->current_object < 0)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err, "ObjectEnd without a matching ObjectBegin");
    pn_status st = pop_state(p, d, 'o');
    if (st != PN_OK) return st;
    pn_object *o = &p->scene->objects[p->current_object];
    o->mesh_count = p->scene->mesh_count - o->first_mesh;
    o->sphere_count = p->scene->sphere_count - o->first_sphere;
    p->current_object = -1;
    return PN_OK;
}

static pn_status d_object_instance(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "the object name", &name);
    if (st != PN_OK) return st;
    if (p->current_object >= 0)
        return pn_loc_error(&d->loc, PN_ERROR_BAD_INPUT, p->err,
                            "ObjectInstance inside the definition of object \"%s\"",
                            p->scene->objects[p->current_object].name);
    warn_motion_once(p, &d->loc);
    char *copy = strdup(name.text);
    if (!copy || !pn_grow_for_append((void **)&p->instances, p->instance_count, sizeof *p->instances)) {
        free(copy);
        return out_of_memory(p);
    }
    p->instances[p->instance_count++] = (pn_pending_instance){copy, name.loc, p->gs.ctm[0]};
    return PN_OK;
}

/* ---- shapes ------------------------------------------------------------------------------ */

/* What every shape of one Shape directive shares. */
typedef struct pn_shape_ctx {
    const pn_token *directive;
    const char *type;
    int material;
    pn_texref alpha;
    bool reverse; /* ReverseOrientation */
    bool swaps;   /* det3(CTM) < 0 */
    int object;
    char *source; /* "file:line", handed to the first mesh, copied for later ones */
} pn_shape_ctx;

static pn_status resolve_material(pn_parser *p, int *out) {
    if (p->gs.material != -1) {
        *out = p->gs.material;
        return PN_OK;
    }
    if (p->default_material < 0) {
        pn_params empty;
        memset(&empty, 0, sizeof empty);
        pn_status st = pn_material_from_pbrt(p->scene, "diffuse", "", &empty, &p->default_material, p->err);
        if (st != PN_OK) return st;
    }
    *out = p->default_material;
    return PN_OK;
}

/* Appends an emission for a shape of world-space `area` if an area light is active. */
static pn_status shape_emission(pn_parser *p, const pn_shape_ctx *sc, double area, int *out) {
    *out = -1;
    if (!p->gs.area_light_on) return PN_OK;
    const pn_srcloc *loc = &sc->directive->loc;
    if (sc->object >= 0) {
        if (!p->warned_object_light) {
            p->warned_object_light = true;
            pn_scene_warn(p->scene,
                          "%s:%d:%d: area lights inside ObjectBegin/ObjectEnd are not supported; the "
                          "shapes of object definitions do not emit",
                          loc->file, loc->line, loc->column);
        }
        return PN_OK;
    }
    pn_area_light_desc desc = p->gs.area_light;
    if (desc.power > 0.0) {
        if (!(area > 0.0)) {
            pn_scene_warn(p->scene,
                          "%s:%d:%d: the %s has zero area; its \"power\" cannot be normalised and it "
                          "does not emit",
                          loc->file, loc->line, loc->column, sc->type);
            return PN_OK;
        }
        pn_area_light_apply_power(&desc, area, sc->type);
    }
    struct pn_scene_s *s = p->scene;
    if (!pn_grow_for_append((void **)&s->emissions, s->emission_count, sizeof *s->emissions)) return out_of_memory(p);
    s->emissions[s->emission_count] = desc.emission;
    *out = s->emission_count++;
    return PN_OK;
}

static char *take_source(pn_shape_ctx *sc) {
    char *s = sc->source;
    sc->source = NULL;
    if (s) return s;
    char buf[600];
    snprintf(buf, sizeof buf, "%s:%d:%d", sc->directive->loc.file, sc->directive->loc.line, sc->directive->loc.column);
    return strdup(buf);
}

/* Turns object-space mesh data into a scene mesh under the CTM. `normals_reverse` is whether
 * the shading normals get flipped (pbrt: ReverseOrientation for meshes). `area_override` > 0
 * replaces the tessellated area for the power normalisation of emitters. */
static pn_status add_mesh(pn_parser *p, pn_shape_ctx *sc, pn_mesh_data *data, bool normals_reverse,
                          double area_override, int *out_index) {
    struct pn_scene_s *s = p->scene;
    const pn_srcloc *loc = &sc->directive->loc;
    if (data->triangle_count == 0 || data->vertex_count == 0) {
        pn_scene_warn(p->scene, "%s:%d:%d: Shape \"%s\" has no triangles; skipped", loc->file, loc->line, loc->column,
                      sc->type);
        pn_mesh_data_free(data);
        if (out_index) *out_index = -1;
        return PN_OK;
    }
    pn_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    bool dropped = false;
    pn_status st = pn_mesh_from_data(data, &p->gs.ctm[0], normals_reverse, &mesh, loc, &dropped, p->err);
    if (st != PN_OK) return st;
    if (dropped)
        pn_scene_warn(p->scene, "%s:%d:%d: Shape \"%s\" has a zero or invalid normal \"N\"; its normals are ignored",
                      loc->file, loc->line, loc->column, sc->type);
    uint32_t degenerate = pn_mesh_degenerate_count(&mesh);
    if (degenerate > 0) {
        /* reported once for the whole scene, at the end (real scenes have many such shapes) */
        if (p->degenerate_shapes == 0) p->degenerate_first = *loc;
        p->degenerate_shapes++;
        p->degenerate_triangles += degenerate;
    }
    mesh.material = sc->material;
    mesh.alpha = sc->alpha;
    mesh.flip_normals = sc->reverse != sc->swaps;
    mesh.object = sc->object;
    mesh.disk = -1;
    double area = area_override > 0.0 ? area_override : (p->gs.area_light_on ? pn_mesh_area(&mesh) : 0.0);
    st = shape_emission(p, sc, area, &mesh.emission);
    if (st == PN_OK) {
        mesh.source = take_source(sc);
        if (!mesh.source || !pn_grow_for_append((void **)&s->meshes, s->mesh_count, sizeof *s->meshes))
            st = out_of_memory(p);
    }
    if (st != PN_OK) {
        free(mesh.positions);
        free(mesh.normals);
        free(mesh.uvs);
        free(mesh.indices);
        free(mesh.source);
        return st;
    }
    if (sc->object < 0) {
        vec3 lo, hi;
        pn_mesh_bounds(&mesh, &lo, &hi);
        grow_bounds(p, lo, hi);
    }
    s->meshes[s->mesh_count] = mesh;
    if (out_index) *out_index = s->mesh_count;
    s->mesh_count++;
    return PN_OK;
}

/* Copies numeric parameter values into a new float array (NULL when count is 0). */
static pn_status to_floats(pn_parser *p, const double *v, int count, float **out) {
    *out = NULL;
    if (count == 0) return PN_OK;
    float *f = malloc((size_t)count * sizeof *f);
    if (!f) return out_of_memory(p);
    for (int i = 0; i < count; i++) f[i] = (float)v[i];
    *out = f;
    return PN_OK;
}

/* Reads P, N, uv of a mesh-like shape (trianglemesh, bilinearmesh, loopsubdiv). */
static pn_status read_vertices(pn_parser *p, const pn_shape_ctx *sc, const pn_params *ps, bool with_attributes,
                               pn_mesh_data *data) {
    memset(data, 0, sizeof *data);
    const double *P, *N = NULL, *UV = NULL;
    int np, nn = 0, nuv = 0;
    pn_status st = pn_params_array(ps, "P", PN_PT_POINT3, 3, &P, &np, p->err);
    if (st != PN_OK) return st;
    if (!pn_params_find(ps, "P"))
        return pn_loc_error(&sc->directive->loc, PN_ERROR_BAD_INPUT, p->err,
                            "Shape \"%s\" needs a \"point3 P\" parameter", sc->type);
    if (with_attributes) {
        if ((st = pn_params_array(ps, "N", PN_PT_NORMAL3, 3, &N, &nn, p->err)) != PN_OK) return st;
        if ((st = pn_params_array(ps, "uv", PN_PT_POINT2, 2, &UV, &nuv, p->err)) != PN_OK) return st;
        if (N && nn != np)
            return pn_param_error(pn_params_find(ps, "N"), p->err, "\"N\" has %d normals but \"P\" has %d vertices",
                                  nn / 3, np / 3);
        if (UV && nuv / 2 != np / 3)
            return pn_param_error(pn_params_find(ps, "uv"), p->err,
                                  "\"uv\" has %d coordinate pairs but \"P\" has %d vertices", nuv / 2, np / 3);
    }
    data->vertex_count = (uint32_t)(np / 3);
    if ((st = to_floats(p, P, np, &data->positions)) != PN_OK) return st;
    if ((st = to_floats(p, N, N ? nn : 0, &data->normals)) != PN_OK) return st;
    if ((st = to_floats(p, UV, UV ? nuv : 0, &data->uvs)) != PN_OK) return st;
    return PN_OK;
}

/* Reads "integer indices" (in groups of `corners`), checking the range; absent indices are
 * 0..corners-1 when there are exactly `corners` vertices. */
static pn_status read_indices(pn_parser *p, const pn_shape_ctx *sc, const pn_params *ps, int corners,
                              uint32_t vertex_count, uint32_t **out, int *count) {
    const double *ix;
    int n;
    *out = NULL;
    *count = 0;
    pn_status st = pn_params_array(ps, "indices", PN_PT_INTEGER, corners, &ix, &n, p->err);
    if (st != PN_OK) return st;
    const pn_param *ip = pn_params_find(ps, "indices");
    if (!ip) {
        if (vertex_count != (uint32_t)corners)
            return pn_loc_error(&sc->directive->loc, PN_ERROR_BAD_INPUT, p->err,
                                "Shape \"%s\" needs an \"integer indices\" parameter (it has %u vertices)", sc->type,
                                vertex_count);
        uint32_t *r = malloc((size_t)corners * sizeof *r);
        if (!r) return out_of_memory(p);
        for (int i = 0; i < corners; i++) r[i] = (uint32_t)i;
        *out = r;
        *count = corners;
        return PN_OK;
    }
    uint32_t *r = malloc((size_t)(n > 0 ? n : 1) * sizeof *r);
    if (!r) return out_of_memory(p);
    for (int i = 0; i < n; i++) {
        if (ix[i] < 0.0 || ix[i] >= (double)vertex_count) {
            free(r);
            return pn_param_error(ip, p->err, "index %d (value %.0f) is out of range: there are %u vertices", i, ix[i],
                                  vertex_count);
        }
        r[i] = (uint32_t)ix[i];
    }
    *out = r;
    *count = n;
    return PN_OK;
}

static pn_status shape_trianglemesh(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    pn_mesh_data data;
    pn_status st = read_vertices(p, sc, ps, true, &data);
    if (st == PN_OK) {
        int n;
        st = read_indices(p, sc, ps, 3, data.vertex_count, &data.indices, &n);
        data.triangle_count = (uint32_t)(n / 3);
    }
    pn_params_find(ps, "S");           /* tangents: not used */
    pn_params_find(ps, "faceIndices"); /* per-face ids for ptex: not used */
    if (st != PN_OK) {
        pn_mesh_data_free(&data);
        return st;
    }
    return add_mesh(p, sc, &data, sc->reverse, 0.0, NULL);
}

static pn_status shape_bilinearmesh(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    pn_mesh_data data;
    pn_status st = read_vertices(p, sc, ps, true, &data);
    uint32_t *quads = NULL;
    int n = 0;
    if (st == PN_OK) st = read_indices(p, sc, ps, 4, data.vertex_count, &quads, &n);
    pn_params_find(ps, "faceIndices");
    pn_params_find(ps, "emissionfilename");
    if (st == PN_OK) {
        /* pbrt's patch corners are p00 p10 p01 p11: split into (p00 p10 p11) and (p00 p11 p01). */
        int patches = n / 4;
        data.indices = malloc((size_t)(patches > 0 ? patches : 1) * 6 * sizeof(uint32_t));
        if (!data.indices) st = out_of_memory(p);
        for (int i = 0; st == PN_OK && i < patches; i++) {
            const uint32_t *q = &quads[4 * i];
            uint32_t *t = &data.indices[6 * i];
            t[0] = q[0];
            t[1] = q[1];
            t[2] = q[3];
            t[3] = q[0];
            t[4] = q[3];
            t[5] = q[2];
        }
        data.triangle_count = (uint32_t)(2 * patches);
    }
    free(quads);
    if (st != PN_OK) {
        pn_mesh_data_free(&data);
        return st;
    }
    return add_mesh(p, sc, &data, sc->reverse, 0.0, NULL);
}

static pn_status shape_loopsubdiv(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    pn_mesh_data data;
    int levels = 3;
    pn_status st = pn_params_int(ps, "levels", 3, &levels, p->err);
    if (st == PN_OK)
        st = read_vertices(p, sc, ps, false, &data);
    else
        memset(&data, 0, sizeof data);
    if (st == PN_OK) {
        int n;
        st = read_indices(p, sc, ps, 3, data.vertex_count, &data.indices, &n);
        data.triangle_count = (uint32_t)(n / 3);
    }
    if (st == PN_OK && levels > 0) {
        if (levels > 6) {
            pn_scene_warn(p->scene, "%s:%d:%d: loopsubdiv \"levels\" %d reduced to 6", sc->directive->loc.file,
                          sc->directive->loc.line, sc->directive->loc.column, levels);
            levels = 6;
        }
        st = pn_loop_subdivide(&data, levels, p->err);
    }
    if (st != PN_OK) {
        pn_mesh_data_free(&data);
        return st;
    }
    return add_mesh(p, sc, &data, sc->reverse, 0.0, NULL);
}

static pn_status shape_plymesh(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    const char *filename = NULL;
    pn_status st = pn_params_string(ps, "filename", NULL, &filename, p->err);
    if (st != PN_OK) return st;
    const pn_param *fp = pn_params_find(ps, "filename");
    if (!filename)
        return pn_loc_error(&sc->directive->loc, PN_ERROR_BAD_INPUT, p->err,
                            "Shape \"plymesh\" needs a \"string filename\" parameter");
    const pn_param *disp = pn_params_find(ps, "displacement");
    pn_params_find(ps, "edgelength");
    if (disp && !p->warned_displacement) {
        p->warned_displacement = true;
        pn_scene_warn(p->scene, "%s:%d:%d: displacement of plymesh shapes is not supported; ignored", disp->loc.file,
                      disp->loc.line, disp->loc.column);
    }
    char *path = pn_path_resolve(ps->base_dir, filename);
    if (!path) return out_of_memory(p);
    if (access(path, R_OK) != 0) {
        int e = errno;
        st = pn_param_error(fp, p->err, "cannot open PLY file \"%s\": %s", path, strerror(e));
        free(path);
        return st;
    }
    pn_ply_mesh ply;
    pn_err perr;
    pn_err_init(&perr);
    st = pn_ply_read(path, &ply, &perr);
    if (st != PN_OK) {
        pn_loc_error(&fp->loc, st, p->err, "%s", perr.message);
        free(path);
        return st;
    }
    if (ply.skipped_face_count > 0)
        pn_scene_warn(p->scene, "%s:%d:%d: \"%s\": %u faces with fewer than 3 vertices skipped", fp->loc.file,
                      fp->loc.line, fp->loc.column, path, ply.skipped_face_count);
    free(path);
    pn_mesh_data data = {ply.vertex_count, ply.triangle_count, ply.positions, ply.normals, ply.uvs, ply.indices};
    return add_mesh(p, sc, &data, sc->reverse, 0.0, NULL);
}

/* Column lengths of the upper 3x3 and whether the matrix is a uniform scale times a rotation. */
static bool is_similarity(const mat4 *m, int columns) {
    double len[3], dots[3];
    vec3 c[3];
    for (int j = 0; j < 3; j++) {
        c[j] = v3((float)m->m[0][j], (float)m->m[1][j], (float)m->m[2][j]);
        len[j] = (double)v3_length(c[j]);
    }
    dots[0] = (double)v3_dot(c[0], c[1]);
    dots[1] = (double)v3_dot(c[0], c[2]);
    dots[2] = (double)v3_dot(c[1], c[2]);
    double lmax = fmax(len[0], len[1]), lmin = fmin(len[0], len[1]);
    if (columns == 3) {
        lmax = fmax(lmax, len[2]);
        lmin = fmin(lmin, len[2]);
    }
    if (!(lmin > 0.0) || lmax / lmin > 1.0 + 1e-4) return false;
    double tol = 1e-4 * lmax * lmax;
    if (fabs(dots[0]) > tol) return false;
    if (columns == 3 && (fabs(dots[1]) > tol || fabs(dots[2]) > tol)) return false;
    return true;
}

static pn_status shape_sphere(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    double radius, zmin, zmax, phimax;
    pn_status st = pn_params_float(ps, "radius", 1.0, &radius, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "zmin", -radius, &zmin, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "zmax", radius, &zmax, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "phimax", 360.0, &phimax, p->err);
    if (st != PN_OK) return st;
    const pn_srcloc *loc = &sc->directive->loc;
    if (!(radius > 0.0)) {
        pn_scene_warn(p->scene, "%s:%d:%d: sphere with radius %g skipped", loc->file, loc->line, loc->column, radius);
        return PN_OK;
    }
    if (zmin > -radius || zmax < radius || phimax < 360.0)
        pn_scene_warn(p->scene,
                      "%s:%d:%d: partial spheres (zmin, zmax, phimax) are not supported; a full sphere "
                      "is used",
                      loc->file, loc->line, loc->column);
    const mat4 *M = &p->gs.ctm[0];
    double det = mat4_det3(M);
    if (!(fabs(det) > 0.0) || !isfinite(det))
        return pn_loc_error(loc, PN_ERROR_BAD_INPUT, p->err, "the transform of the sphere is singular");
    if (!is_similarity(M, 3))
        pn_scene_warn(p->scene,
                      "%s:%d:%d: sphere under a non-uniform scale or shear; approximated by a sphere of "
                      "the same volume",
                      loc->file, loc->line, loc->column);
    if (sc->alpha.texture >= 0 || sc->alpha.value.x < 1.0f)
        pn_scene_warn(p->scene, "%s:%d:%d: \"alpha\" is not supported on spheres; ignored", loc->file, loc->line,
                      loc->column);
    pn_sphere sp;
    memset(&sp, 0, sizeof sp);
    sp.center = mat4_apply_point(M, v3(0, 0, 0));
    sp.axis[0] = v3_normalize(mat4_apply_vector(M, v3(1, 0, 0)));
    sp.axis[1] = v3_normalize(mat4_apply_vector(M, v3(0, 1, 0)));
    sp.axis[2] = v3_normalize(mat4_apply_vector(M, v3(0, 0, 1)));
    sp.radius = (float)(radius * cbrt(fabs(det)));
    sp.material = sc->material;
    sp.flip_normals = sc->reverse != sc->swaps;
    sp.object = sc->object;
    if (!v3_is_finite(sp.center) || !isfinite(sp.radius))
        return pn_loc_error(loc, PN_ERROR_BAD_INPUT, p->err, "the sphere's centre or radius is not finite");
    double r = (double)sp.radius;
    st = shape_emission(p, sc, 4.0 * PN_PI_D * r * r, &sp.emission);
    if (st != PN_OK) return st;
    struct pn_scene_s *s = p->scene;
    sp.source = take_source(sc);
    if (!sp.source || !pn_grow_for_append((void **)&s->spheres, s->sphere_count, sizeof *s->spheres)) {
        free(sp.source);
        return out_of_memory(p);
    }
    s->spheres[s->sphere_count++] = sp;
    if (sc->object < 0) {
        vec3 e = v3(sp.radius, sp.radius, sp.radius);
        grow_bounds(p, v3_sub(sp.center, e), v3_add(sp.center, e));
    }
    return PN_OK;
}

static pn_status shape_disk(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    double height, radius, inner, phimax;
    pn_status st = pn_params_float(ps, "height", 0.0, &height, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "radius", 1.0, &radius, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "innerradius", 0.0, &inner, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "phimax", 360.0, &phimax, p->err);
    if (st != PN_OK) return st;
    const pn_srcloc *loc = &sc->directive->loc;
    if (!(radius > 0.0) || inner < 0.0 || inner >= radius) {
        pn_scene_warn(p->scene, "%s:%d:%d: disk with radius %g and inner radius %g skipped", loc->file, loc->line,
                      loc->column, radius, inner);
        return PN_OK;
    }
    if (phimax < 360.0)
        pn_scene_warn(p->scene, "%s:%d:%d: partial disks (phimax) are not supported; a full disk is used", loc->file,
                      loc->line, loc->column);
    const mat4 *M = &p->gs.ctm[0];
    mat4 inv;
    if (!mat4_inverse(*M, &inv))
        return pn_loc_error(loc, PN_ERROR_BAD_INPUT, p->err, "the transform of the disk is singular");
    if (!is_similarity(M, 2))
        pn_scene_warn(p->scene,
                      "%s:%d:%d: disk under a non-uniform scale or shear; its analytic light uses a "
                      "circle of the same area",
                      loc->file, loc->line, loc->column);
    /* Winding is reversed under a mirroring transform so that the tessellation's geometric
     * normal, after pbrt's flip for ReverseOrientation XOR handedness, equals the disk's. */
    pn_mesh_data data;
    st = pn_tessellate_disk(height, radius, inner, 360.0, PN_DISK_SEGMENTS, sc->swaps, &data, p->err);
    if (st != PN_OK) return st;
    vec3 ex = mat4_apply_vector(M, v3(1, 0, 0)), ey = mat4_apply_vector(M, v3(0, 1, 0));
    double area_scale = (double)v3_length(v3_cross(ex, ey));
    double scale = sqrt(area_scale);
    double world_area = PN_PI_D * (radius * radius - inner * inner) * area_scale;
    bool world = sc->object < 0;
    int mesh_index = -1;
    st = add_mesh(p, sc, &data, sc->reverse, world_area, &mesh_index);
    if (st != PN_OK || mesh_index < 0 || !world) return st;
    struct pn_scene_s *s = p->scene;
    pn_disk dk;
    dk.center = mat4_apply_point(M, v3(0, 0, (float)height));
    vec3 n = v3_normalize(mat4_apply_normal(&inv, v3(0, 0, 1)));
    dk.normal = (sc->reverse != sc->swaps) ? v3_neg(n) : n;
    dk.radius = (float)(radius * scale);
    dk.inner_radius = (float)(inner * scale);
    dk.mesh = mesh_index;
    if (!pn_grow_for_append((void **)&s->disks, s->disk_count, sizeof *s->disks)) return out_of_memory(p);
    s->meshes[mesh_index].disk = s->disk_count;
    s->disks[s->disk_count++] = dk;
    return PN_OK;
}

static pn_status shape_cylinder(pn_parser *p, pn_shape_ctx *sc, pn_params *ps) {
    double radius, zmin, zmax, phimax;
    pn_status st = pn_params_float(ps, "radius", 1.0, &radius, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "zmin", -1.0, &zmin, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "zmax", 1.0, &zmax, p->err);
    if (st == PN_OK) st = pn_params_float(ps, "phimax", 360.0, &phimax, p->err);
    if (st != PN_OK) return st;
    const pn_srcloc *loc = &sc->directive->loc;
    if (zmin > zmax) {
        double t = zmin;
        zmin = zmax;
        zmax = t;
    }
    if (!(radius > 0.0) || !(zmax > zmin) || !(phimax > 0.0)) {
        pn_scene_warn(p->scene, "%s:%d:%d: empty cylinder skipped", loc->file, loc->line, loc->column);
        return PN_OK;
    }
    if (!p->warned_cylinder) {
        p->warned_cylinder = true;
        pn_scene_warn(p->scene, "%s:%d:%d: cylinders are tessellated into %d-segment triangle meshes", loc->file,
                      loc->line, loc->column, PN_CYLINDER_SEGMENTS);
    }
    pn_mesh_data data;
    st =
        pn_tessellate_cylinder(radius, zmin, zmax, fmin(phimax, 360.0), PN_CYLINDER_SEGMENTS, sc->swaps, &data, p->err);
    if (st != PN_OK) return st;
    /* Quadric normals flip with ReverseOrientation XOR handedness (pbrt), unlike mesh normals. */
    return add_mesh(p, sc, &data, sc->reverse != sc->swaps, 0.0, NULL);
}

static pn_status d_shape(pn_parser *p, const pn_token *d) {
    pn_token type;
    pn_status st = read_string(p, d, "the shape type", &type);
    if (st != PN_OK) return st;
    pn_params ps;
    st = read_params(p, d, &ps);
    int own = ps.count;
    if (st == PN_OK) st = add_attr_defaults(p, PN_ATTR_SHAPE, &ps);
    if (st != PN_OK) {
        pn_params_free(&ps);
        return st;
    }
    typedef pn_status (*shape_fn)(pn_parser *, pn_shape_ctx *, pn_params *);
    static const struct {
        const char *name;
        shape_fn fn;
    } shapes[] = {{"trianglemesh", shape_trianglemesh},
                  {"plymesh", shape_plymesh},
                  {"sphere", shape_sphere},
                  {"disk", shape_disk},
                  {"bilinearmesh", shape_bilinearmesh},
                  {"loopsubdiv", shape_loopsubdiv},
                  {"cylinder", shape_cylinder}};
    shape_fn fn = NULL;
    for (size_t i = 0; i < sizeof shapes / sizeof shapes[0]; i++)
        if (strcmp(type.text, shapes[i].name) == 0) fn = shapes[i].fn;
    if (!fn) {
        if (strcmp(type.text, "curve") == 0) {
            if (!p->warned_curve) {
                p->warned_curve = true;
                pn_scene_warn(p->scene, "%s:%d:%d: curve shapes are not supported; skipped", type.loc.file,
                              type.loc.line, type.loc.column);
            }
        } else {
            pn_scene_warn(p->scene, "%s:%d:%d: unknown shape type \"%s\"; skipped", type.loc.file, type.loc.line,
                          type.loc.column, type.text);
        }
        pn_params_free(&ps);
        return PN_OK;
    }
    warn_motion_once(p, &d->loc);
    pn_shape_ctx sc;
    memset(&sc, 0, sizeof sc);
    sc.directive = d;
    sc.type = type.text;
    sc.reverse = p->gs.reverse_orientation;
    sc.swaps = mat4_det3(&p->gs.ctm[0]) < 0.0;
    sc.object = p->current_object;
    st = resolve_material(p, &sc.material);
    if (st == PN_OK) st = pn_params_texref(p->scene, &ps, "alpha", true, v3(1, 1, 1), &sc.alpha, p->err);
    if (st == PN_OK) st = fn(p, &sc, &ps);
    if (st == PN_OK) warn_unused(p, &ps, own, d, type.text);
    free(sc.source);
    pn_params_free(&ps);
    return st;
}

/* ---- Include ----------------------------------------------------------------------------- */

static pn_status open_file(pn_parser *p, const char *path, const pn_srcloc *at) {
    const char *kept = keep_string(p, strdup(path));
    if (!kept) return out_of_memory(p);
    if (p->depth == 0) {
        p->search_dir = keep_string(p, dir_of(path));
        if (!p->search_dir) return out_of_memory(p);
    }
    pn_open_file *f = &p->files[p->depth];
    pn_status st = pn_tokenizer_open(&f->tz, kept, at, p->err);
    if (st != PN_OK) return st;
    p->depth++;
    return PN_OK;
}

static pn_status d_include(pn_parser *p, const pn_token *d) {
    pn_token name;
    pn_status st = read_string(p, d, "a file name", &name);
    if (st != PN_OK) return st;
    if (p->depth > PN_MAX_INCLUDE_DEPTH)
        return pn_loc_error(&name.loc, PN_ERROR_BAD_INPUT, p->err,
                            "Include nesting is deeper than %d files (does a file include itself?)",
                            PN_MAX_INCLUDE_DEPTH);
    char *path = pn_path_resolve(search_dir(p), name.text);
    if (!path) return out_of_memory(p);
    st = open_file(p, path, &name.loc);
    free(path);
    return st;
}

/* ---- directive table --------------------------------------------------------------------- */

enum { PN_ANYWHERE = 0, PN_OPTIONS_ONLY = 1, PN_WORLD_ONLY = 2 };

typedef pn_status (*pn_directive_fn)(pn_parser *p, const pn_token *d);

typedef struct pn_directive {
    const char *name;
    pn_directive_fn fn;
    int block;
} pn_directive;

static const pn_directive pn_directives[] = {
    {"AttributeBegin", d_attribute_begin, PN_ANYWHERE},
    {"AttributeEnd", d_attribute_end, PN_ANYWHERE},
    {"Shape", d_shape, PN_WORLD_ONLY},
    {"Translate", d_translate, PN_ANYWHERE},
    {"NamedMaterial", d_named_material, PN_WORLD_ONLY},
    {"Material", d_material, PN_WORLD_ONLY},
    {"Transform", d_transform, PN_ANYWHERE},
    {"ConcatTransform", d_concat_transform, PN_ANYWHERE},
    {"Scale", d_scale, PN_ANYWHERE},
    {"Rotate", d_rotate, PN_ANYWHERE},
    {"LookAt", d_look_at, PN_ANYWHERE},
    {"Identity", d_identity, PN_ANYWHERE},
    {"AreaLightSource", d_area_light_source, PN_WORLD_ONLY},
    {"LightSource", d_light_source, PN_WORLD_ONLY},
    {"MakeNamedMaterial", d_make_named_material, PN_WORLD_ONLY},
    {"Texture", d_texture, PN_WORLD_ONLY},
    {"ObjectBegin", d_object_begin, PN_WORLD_ONLY},
    {"ObjectEnd", d_object_end, PN_WORLD_ONLY},
    {"ObjectInstance", d_object_instance, PN_WORLD_ONLY},
    {"ReverseOrientation", d_reverse_orientation, PN_ANYWHERE},
    {"TransformBegin", d_transform_begin, PN_ANYWHERE},
    {"TransformEnd", d_transform_end, PN_ANYWHERE},
    {"CoordinateSystem", d_coordinate_system, PN_ANYWHERE},
    {"CoordSysTransform", d_coord_sys_transform, PN_ANYWHERE},
    {"ActiveTransform", d_active_transform, PN_ANYWHERE},
    {"TransformTimes", d_transform_times, PN_OPTIONS_ONLY},
    {"Attribute", d_attribute, PN_ANYWHERE},
    {"Option", d_option, PN_ANYWHERE},
    {"ColorSpace", d_color_space, PN_ANYWHERE},
    {"Camera", d_camera, PN_OPTIONS_ONLY},
    {"Film", d_film, PN_OPTIONS_ONLY},
    {"PixelFilter", d_pixel_filter, PN_OPTIONS_ONLY},
    {"Sampler", d_sampler, PN_OPTIONS_ONLY},
    {"Integrator", d_integrator, PN_OPTIONS_ONLY},
    {"Accelerator", d_accelerator, PN_OPTIONS_ONLY},
    {"MakeNamedMedium", d_make_named_medium, PN_ANYWHERE},
    {"MediumInterface", d_medium_interface, PN_ANYWHERE},
    {"WorldBegin", d_world_begin, PN_ANYWHERE},
    {"WorldEnd", d_world_end, PN_WORLD_ONLY},
    {"Include", d_include, PN_ANYWHERE},
    {"Import", d_include, PN_ANYWHERE},
};

static pn_status dispatch(pn_parser *p, const pn_token *t) {
    if (t->kind != PN_TOKEN_WORD) {
        if (t->kind == PN_TOKEN_STRING)
            return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err, "expected a directive, found the string \"%s\"",
                                t->text);
        return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err, "expected a directive, found '%c'", t->text[0]);
    }
    for (size_t i = 0; i < sizeof pn_directives / sizeof pn_directives[0]; i++) {
        const pn_directive *dir = &pn_directives[i];
        if (!pn_token_is(t, dir->name)) continue;
        if (dir->block == PN_WORLD_ONLY && !p->in_world)
            return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err, "%s is only allowed after WorldBegin", dir->name);
        if (dir->block == PN_OPTIONS_ONLY && p->in_world)
            return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err, "%s is only allowed before WorldBegin", dir->name);
        return dir->fn(p, t);
    }
    int shown = t->len > 60 ? 60 : (int)t->len;
    if (pn_token_is_numeric(t))
        return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err,
                            "unexpected number \"%.*s\" where a directive was expected (too many arguments?)", shown,
                            t->text);
    return pn_loc_error(&t->loc, PN_ERROR_BAD_INPUT, p->err, "unknown directive \"%.*s\"", shown, t->text);
}

/* ---- end of parsing ---------------------------------------------------------------------- */

static pn_status resolve_pending(pn_parser *p) {
    struct pn_scene_s *s = p->scene;
    if (p->pending_material_count > 0) {
        int *resolved = malloc((size_t)p->pending_material_count * sizeof *resolved);
        if (!resolved) return out_of_memory(p);
        for (int i = 0; i < p->pending_material_count; i++) {
            resolved[i] = pn_scene_find_material(s, p->pending_materials[i].name);
            if (resolved[i] < 0) {
                /* Only an error if some shape actually used it. */
                bool used = false;
                for (int m = 0; m < s->mesh_count && !used; m++) used = s->meshes[m].material == -2 - i;
                for (int m = 0; m < s->sphere_count && !used; m++) used = s->spheres[m].material == -2 - i;
                if (used) {
                    free(resolved);
                    const pn_pending_material *pm = &p->pending_materials[i];
                    return pn_loc_error(&pm->loc, PN_ERROR_BAD_INPUT, p->err, "undefined named material \"%s\"",
                                        pm->name);
                }
            }
        }
        for (int m = 0; m < s->mesh_count; m++)
            if (s->meshes[m].material <= -2) s->meshes[m].material = resolved[-2 - s->meshes[m].material];
        for (int m = 0; m < s->sphere_count; m++)
            if (s->spheres[m].material <= -2) s->spheres[m].material = resolved[-2 - s->spheres[m].material];
        free(resolved);
    }
    if (p->instance_count > 0) {
        s->instances = malloc((size_t)p->instance_count * sizeof *s->instances);
        if (!s->instances) return out_of_memory(p);
        for (int i = 0; i < p->instance_count; i++) {
            const pn_pending_instance *pi = &p->instances[i];
            int o = -1;
            for (int k = 0; k < s->object_count && o < 0; k++)
                if (strcmp(s->objects[k].name, pi->name) == 0) o = k;
            if (o < 0)
                return pn_loc_error(&pi->loc, PN_ERROR_BAD_INPUT, p->err, "ObjectInstance of undefined object \"%s\"",
                                    pi->name);
            s->instances[s->instance_count].object = o;
            s->instances[s->instance_count].world_from_object = pi->world_from_object;
            s->instance_count++;
        }
    }
    return PN_OK;
}

static void instance_bounds(pn_parser *p) {
    struct pn_scene_s *s = p->scene;
    if (s->instance_count == 0) return;
    vec3 *olo = malloc((size_t)s->object_count * sizeof *olo);
    vec3 *ohi = malloc((size_t)s->object_count * sizeof *ohi);
    if (!olo || !ohi) {
        free(olo);
        free(ohi);
        return;
    }
    for (int o = 0; o < s->object_count; o++) {
        const pn_object *ob = &s->objects[o];
        vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
        for (int m = 0; m < ob->mesh_count; m++) {
            vec3 a, b;
            pn_mesh_bounds(&s->meshes[ob->first_mesh + m], &a, &b);
            lo = v3_min(lo, a);
            hi = v3_max(hi, b);
        }
        for (int k = 0; k < ob->sphere_count; k++) {
            const pn_sphere *sp = &s->spheres[ob->first_sphere + k];
            vec3 e = v3(sp->radius, sp->radius, sp->radius);
            lo = v3_min(lo, v3_sub(sp->center, e));
            hi = v3_max(hi, v3_add(sp->center, e));
        }
        olo[o] = lo;
        ohi[o] = hi;
    }
    for (int i = 0; i < s->instance_count; i++) {
        const pn_instance *in = &s->instances[i];
        vec3 lo = olo[in->object], hi = ohi[in->object];
        if (!(lo.x <= hi.x)) continue;
        for (int c = 0; c < 8; c++) {
            vec3 corner = v3(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
            vec3 w = mat4_apply_point(&in->world_from_object, corner);
            grow_bounds(p, w, w);
        }
    }
    free(olo);
    free(ohi);
}

static pn_status finish_camera(pn_parser *p) {
    pn_camera_def *cam = &p->scene->camera;
    /* pbrt-v4 (scene.cpp, film.cpp): the exposure time is shutterclose - shutteropen of the
     * camera's parameters as written (a reversed pair is not swapped for this), and a shutter that
     * does not open stops the render; the imaging ratio is exposure time * ISO / 100. */
    double exposure = (double)cam->shutter_close - (double)cam->shutter_open;
    if (!(exposure > 0.0)) {
        pn_srcloc loc = p->camera_loc;
        return pn_loc_error(&loc, PN_ERROR_BAD_INPUT, p->err,
                            "the camera's shutter does not open: shutterclose %g - shutteropen %g is not positive",
                            (double)cam->shutter_close, (double)cam->shutter_open);
    }
    cam->imaging_ratio = (float)(exposure * (double)cam->iso / 100.0);
    if (!p->screen_window_given) {
        double aspect = p->frame_aspect > 0.0 ? p->frame_aspect : (double)cam->width / (double)cam->height;
        if (aspect > 1.0) {
            cam->screen_window[0] = (float)-aspect;
            cam->screen_window[1] = (float)aspect;
            cam->screen_window[2] = -1.0f;
            cam->screen_window[3] = 1.0f;
        } else {
            cam->screen_window[0] = -1.0f;
            cam->screen_window[1] = 1.0f;
            cam->screen_window[2] = (float)(-1.0 / aspect);
            cam->screen_window[3] = (float)(1.0 / aspect);
        }
    }
    return PN_OK;
}

static pn_status camera_defaults(pn_parser *p) {
    pn_camera_def *cam = &p->scene->camera;
    cam->camera_from_world = mat4_identity();
    cam->world_from_camera = mat4_identity();
    cam->fov_deg = 90.0f;
    cam->focal_distance = 1e6f;
    cam->width = 1280;
    cam->height = 720;
    cam->crop[0] = 0.0f;
    cam->crop[1] = 1.0f;
    cam->crop[2] = 0.0f;
    cam->crop[3] = 1.0f;
    cam->filter = PN_FILTER_GAUSSIAN;
    cam->filter_radius[0] = cam->filter_radius[1] = 1.5f;
    cam->gaussian_sigma = 0.5f;
    cam->mitchell_b = cam->mitchell_c = 1.0f / 3.0f;
    cam->pixel_samples = 16;
    cam->max_depth = 5;
    cam->shutter_open = 0.0f;
    cam->shutter_close = 1.0f;
    cam->iso = 100.0f;
    cam->imaging_ratio = 1.0f;
    cam->film_filename = strdup("");
    cam->integrator_name = strdup("volpath");
    if (!cam->film_filename || !cam->integrator_name) return out_of_memory(p);
    return PN_OK;
}

static pn_status parse_all(pn_parser *p, const char *path) {
    pn_status st = camera_defaults(p);
    if (st != PN_OK) return st;
    st = open_file(p, path, NULL);
    if (st != PN_OK) return st;
    pn_srcloc end_loc = {NULL, 0, 0};
    while (p->depth > 0) {
        pn_token t;
        st = pn_tokenizer_next(cur(p), &t, p->err);
        if (st != PN_OK) return st;
        if (t.kind == PN_TOKEN_EOF) {
            end_loc = t.loc;
            pn_tokenizer_close(cur(p));
            p->depth--;
            continue;
        }
        st = dispatch(p, &t);
        if (st != PN_OK) return st;
    }
    if (!p->in_world)
        return pn_loc_error(&end_loc, PN_ERROR_BAD_INPUT, p->err,
                            "the file ends before WorldBegin: there is no scene to render");
    if (p->stack_count > 0) {
        const pn_pushed_state *top = &p->stack[p->stack_count - 1];
        return pn_loc_error(&top->loc, PN_ERROR_BAD_INPUT, p->err, "%s is never closed (the file ends first)",
                            begin_name(top->kind));
    }
    st = resolve_pending(p);
    if (st != PN_OK) return st;
    if (p->degenerate_shapes > 0) {
        const pn_srcloc *l = &p->degenerate_first;
        pn_scene_warn(p->scene,
                      "%s:%d:%d: %llu degenerate (zero-area) triangles in %d shape%s, the first here; "
                      "they are kept but cannot be hit or emit",
                      l->file, l->line, l->column, (unsigned long long)p->degenerate_triangles, p->degenerate_shapes,
                      p->degenerate_shapes == 1 ? "" : "s");
    }
    instance_bounds(p);
    return finish_camera(p);
}

static void parser_cleanup(pn_parser *p) {
    while (p->depth > 0) pn_tokenizer_close(&p->files[--p->depth].tz);
    truncate_attrs(p, 0);
    free(p->attrs);
    free(p->stack);
    for (int i = 0; i < p->named_count; i++) free(p->named[i].name);
    free(p->named);
    for (int i = 0; i < p->instance_count; i++) free(p->instances[i].name);
    free(p->instances);
    for (int i = 0; i < p->pending_material_count; i++) free(p->pending_materials[i].name);
    free(p->pending_materials);
    for (int i = 0; i < p->string_count; i++) free(p->strings[i]);
    free(p->strings);
}

pn_status pn_scene_parse(pn_context ctx, const char *path, struct pn_scene_s **out, pn_err *err) {
    if (out) *out = NULL;
    if (!path || !out) return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "pn_scene_parse: NULL argument");
    struct pn_scene_s *scene = calloc(1, sizeof *scene);
    pn_parser *p = calloc(1, sizeof *p);
    if (!scene || !p) {
        free(scene);
        free(p);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    }
    scene->ctx = ctx;
    scene->path = strdup(path);
    p->scene = scene;
    p->err = err;
    p->gs.ctm[0] = p->gs.ctm[1] = mat4_identity();
    p->gs.active = 3;
    p->gs.material = -1;
    p->current_object = -1;
    p->default_material = -1;
    p->bounds_lo = v3(INFINITY, INFINITY, INFINITY);
    p->bounds_hi = v3(-INFINITY, -INFINITY, -INFINITY);
    pn_status st = scene->path ? parse_all(p, path) : out_of_memory(p);
    if (st == PN_OK) {
        if (p->bounds_lo.x <= p->bounds_hi.x) {
            scene->bounds_min = p->bounds_lo;
            scene->bounds_max = p->bounds_hi;
        } else {
            scene->bounds_min = scene->bounds_max = v3(0, 0, 0);
        }
    }
    parser_cleanup(p);
    free(p);
    if (st != PN_OK) {
        if (err && err->status == PN_OK) pn_err_set(err, st, "%s: the scene could not be parsed", path);
        pn_scene_parse_free(scene);
        return st;
    }
    *out = scene;
    return PN_OK;
}

void pn_scene_parse_free(struct pn_scene_s *scene) {
    if (!scene) return;
    free(scene->path);
    free(scene->camera.film_filename);
    free(scene->camera.integrator_name);
    for (int i = 0; i < scene->mesh_count; i++) {
        pn_mesh *m = &scene->meshes[i];
        free(m->positions);
        free(m->normals);
        free(m->uvs);
        free(m->indices);
        free(m->source);
    }
    free(scene->meshes);
    for (int i = 0; i < scene->sphere_count; i++) free(scene->spheres[i].source);
    free(scene->spheres);
    free(scene->disks);
    for (int i = 0; i < scene->object_count; i++) free(scene->objects[i].name);
    free(scene->objects);
    free(scene->instances);
    for (int i = 0; i < scene->material_count; i++) {
        free(scene->materials[i].name);
        free(scene->materials[i].description);
    }
    free(scene->materials);
    for (int i = 0; i < scene->texture_count; i++) free(scene->textures[i].name);
    for (int i = 0; i < scene->mipmap_count; i++) pn_mipmap_free(&scene->mipmaps[i]);
    free(scene->mipmaps);
    free(scene->textures);
    for (int i = 0; i < scene->image_count; i++) {
        free(scene->images[i].rgb);
        free(scene->images[i].path);
    }
    free(scene->images);
    free(scene->emissions);
    for (int i = 0; i < scene->light_def_count; i++) free(scene->light_defs[i].source);
    free(scene->light_defs);
    for (int i = 0; i < scene->photometry_count; i++) pn_photometry_free(scene->photometries[i]);
    free(scene->photometries);
    for (int i = 0; i < scene->spd_count; i++) pn_spd_free(scene->spds[i]);
    free(scene->spds);
    pn_warning_list_free(&scene->warnings);
    free(scene);
}
