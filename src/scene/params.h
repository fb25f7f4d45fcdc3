/* params.h — pbrt-v4 parameter lists ("type name" [values]) as the tokenizer/parser hands them to
 * the builders of materials, textures, lights and shapes, with typed getters that report errors
 * at the parameter's location ("file:line:column: message").
 *
 * Implemented in scene/params.c. The spectrum-aware getters (rgb / blackbody / spectrum values and
 * textures) are in scene/spectrum.c and scene/texture.c and declared in scene/build.h.
 */
#ifndef PN_SCENE_PARAMS_H
#define PN_SCENE_PARAMS_H

#include "core/error.h"
#include "core/vecmath.h"

#include <stdbool.h>

/* A position in a scene file. `file` is owned by the parser and lives as long as the parse. */
typedef struct pn_srcloc {
    const char *file;
    int line, column; /* 1-based */
} pn_srcloc;

/* Parameter types. pbrt-v3 spellings are accepted and mapped: "point" -> POINT3,
 * "vector" -> VECTOR3, "normal" -> NORMAL3, "color" -> RGB. */
typedef enum pn_param_type {
    PN_PT_INTEGER = 0,
    PN_PT_FLOAT,
    PN_PT_POINT2,
    PN_PT_VECTOR2,
    PN_PT_POINT3,
    PN_PT_VECTOR3,
    PN_PT_NORMAL3,
    PN_PT_RGB,
    PN_PT_BLACKBODY,
    PN_PT_SPECTRUM, /* numbers (lambda, value pairs) or one string (named spectrum or .spd file) */
    PN_PT_BOOL,
    PN_PT_STRING,
    PN_PT_TEXTURE
} pn_param_type;

typedef struct pn_param {
    pn_param_type type;
    char *name;
    pn_srcloc loc; /* of the quoted "type name" */
    double *nums;  /* numeric values (bool: 0 / 1) */
    int num_count;
    char **strs; /* string, texture and string-form spectrum values */
    int str_count;
    bool used; /* set by the getters; unused parameters are reported as warnings */
} pn_param;

typedef struct pn_params {
    pn_param *items;
    int count;
    const char *base_dir; /* pbrt-v4's search directory: the top-level scene file's folder, against which
                             every relative path resolves (also in included files) */
    pn_srcloc loc;        /* of the directive itself */
} pn_params;

/* Frees the values (not the pn_params struct itself). */
void pn_params_free(pn_params *ps);

/* The parameter called `name` (the last one if repeated), marked used; NULL if absent. */
const pn_param *pn_params_find(const pn_params *ps, const char *name);

/* Sets err to "file:line:column: <message>" at the parameter's location and returns
 * PN_ERROR_BAD_INPUT. */
pn_status pn_param_error(const pn_param *p, pn_err *err, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Typed getters: when the parameter is absent, *out = def and PN_OK. When it is present with the
 * wrong type or the wrong number of values, err is set at its location and PN_ERROR_BAD_INPUT is
 * returned. Integers are accepted where floats are expected. */
pn_status pn_params_float(const pn_params *ps, const char *name, double def, double *out, pn_err *err);
pn_status pn_params_int(const pn_params *ps, const char *name, int def, int *out, pn_err *err);
pn_status pn_params_bool(const pn_params *ps, const char *name, bool def, bool *out, pn_err *err);
/* *out points into the parameter (valid while ps lives) or is `def`. */
pn_status pn_params_string(const pn_params *ps, const char *name, const char *def, const char **out, pn_err *err);
/* A POINT3/VECTOR3/NORMAL3 (any of the three) with exactly 3 values. */
pn_status pn_params_vec3(const pn_params *ps, const char *name, vec3 def, vec3 *out, pn_err *err);
/* Arrays: *out points into the parameter (NULL and 0 when absent). `type` is checked (INTEGER
 * arrays may be read with PN_PT_INTEGER only; FLOAT also accepts integers; POINT3 also accepts
 * VECTOR3/NORMAL3 values); `multiple_of` checks num_count % multiple_of == 0. */
pn_status pn_params_array(const pn_params *ps, const char *name, pn_param_type type, int multiple_of,
                          const double **out, int *count, pn_err *err);

struct pn_scene_s;

/* Adds the warning "file:line:column: <message>" at loc to the scene (pn_scene_warn). */
void pn_warn_at(struct pn_scene_s *scene, pn_srcloc loc, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* A malloc'ed copy of s (NULL when out of memory). */
char *pn_strdup(const char *s);

/* The one resolver of relative paths (pbrt-v4 ResolveFilename): joins path to base_dir, the
 * search directory; absolute paths and an empty base_dir return path as it is. Caller frees. */
char *pn_path_resolve(const char *base_dir, const char *path);

#endif
