/* params.c — pbrt-v4 parameter lists: parsing "type name" [values] from the tokenizer, typed
 * getters with errors at the parameter's location, and relative path resolution. */
#include "scene/params.h"
#include "scene/parser_internal.h"
#include "scene/tokenizer.h"

#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct pn_type_spelling {
    const char *name;
    pn_param_type type;
} pn_type_spelling;

/* pbrt-v4 names first (used when printing), then the pbrt-v3 spellings it still accepts. */
static const pn_type_spelling pn_type_spellings[] = {
    {"integer", PN_PT_INTEGER},   {"float", PN_PT_FLOAT},   {"point2", PN_PT_POINT2},
    {"vector2", PN_PT_VECTOR2},   {"point3", PN_PT_POINT3}, {"vector3", PN_PT_VECTOR3},
    {"normal3", PN_PT_NORMAL3},   {"rgb", PN_PT_RGB},       {"blackbody", PN_PT_BLACKBODY},
    {"spectrum", PN_PT_SPECTRUM}, {"bool", PN_PT_BOOL},     {"string", PN_PT_STRING},
    {"texture", PN_PT_TEXTURE},   {"point", PN_PT_POINT3},  {"vector", PN_PT_VECTOR3},
    {"normal", PN_PT_NORMAL3},    {"color", PN_PT_RGB},
};

const char *pn_param_type_name(pn_param_type type) {
    for (size_t i = 0; i < sizeof pn_type_spellings / sizeof pn_type_spellings[0]; i++)
        if (pn_type_spellings[i].type == type) return pn_type_spellings[i].name;
    return "?";
}

static bool lookup_type(const char *s, size_t n, pn_param_type *out) {
    for (size_t i = 0; i < sizeof pn_type_spellings / sizeof pn_type_spellings[0]; i++) {
        const char *name = pn_type_spellings[i].name;
        if (strlen(name) == n && memcmp(name, s, n) == 0) {
            *out = pn_type_spellings[i].type;
            return true;
        }
    }
    return false;
}

void pn_params_free(pn_params *ps) {
    if (!ps) return;
    for (int i = 0; i < ps->count; i++) {
        pn_param *p = &ps->items[i];
        free(p->name);
        free(p->nums);
        for (int j = 0; j < p->str_count; j++) free(p->strs[j]);
        free(p->strs);
    }
    free(ps->items);
    ps->items = NULL;
    ps->count = 0;
}

const pn_param *pn_params_find(const pn_params *ps, const char *name) {
    if (!ps) return NULL;
    for (int i = ps->count - 1; i >= 0; i--) {
        pn_param *p = &ps->items[i];
        if (strcmp(p->name, name) == 0) {
            p->used = true;
            return p;
        }
    }
    return NULL;
}

pn_status pn_param_error(const pn_param *p, pn_err *err, const char *fmt, ...) {
    char msg[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pn_loc_error(&p->loc, PN_ERROR_BAD_INPUT, err, "%s", msg);
}

/* ---- parsing ----------------------------------------------------------------------------- */

static pn_status oom(pn_err *err) {
    return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
}

static pn_status push_number(pn_param *p, int *cap, double v, pn_err *err) {
    if (p->num_count == *cap) {
        if (*cap > INT_MAX / 2) return oom(err);
        int ncap = *cap ? *cap * 2 : 16;
        double *n = realloc(p->nums, (size_t)ncap * sizeof *n);
        if (!n) return oom(err);
        p->nums = n;
        *cap = ncap;
    }
    p->nums[p->num_count++] = v;
    return PN_OK;
}

static pn_status push_string(pn_param *p, int *cap, const char *s, size_t len, pn_err *err) {
    if (p->str_count == *cap) {
        if (*cap > INT_MAX / 2) return oom(err);
        int ncap = *cap ? *cap * 2 : 4;
        char **n = realloc(p->strs, (size_t)ncap * sizeof *n);
        if (!n) return oom(err);
        p->strs = n;
        *cap = ncap;
    }
    char *c = malloc(len + 1);
    if (!c) return oom(err);
    memcpy(c, s, len);
    c[len] = '\0';
    p->strs[p->str_count++] = c;
    return PN_OK;
}

/* Adds one value token to the parameter, checking it against the declared type. */
static pn_status add_value(pn_param *p, const pn_token *tok, int *num_cap, int *str_cap, pn_err *err) {
    const char *tn = pn_param_type_name(p->type);
    if (p->type == PN_PT_BOOL) {
        bool is_true = (tok->kind == PN_TOKEN_WORD || tok->kind == PN_TOKEN_STRING) && tok->len == 4 &&
                       memcmp(tok->text, "true", 4) == 0;
        bool is_false = (tok->kind == PN_TOKEN_WORD || tok->kind == PN_TOKEN_STRING) && tok->len == 5 &&
                        memcmp(tok->text, "false", 5) == 0;
        if (!is_true && !is_false)
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                "parameter \"bool %s\" expects true or false, found \"%.*s\"", p->name,
                                (int)(tok->len > 60 ? 60 : tok->len), tok->text);
        return push_number(p, num_cap, is_true ? 1.0 : 0.0, err);
    }
    if (p->type == PN_PT_STRING || p->type == PN_PT_TEXTURE) {
        if (tok->kind != PN_TOKEN_STRING)
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                "parameter \"%s %s\" expects quoted strings, found \"%.*s\"", tn, p->name,
                                (int)(tok->len > 60 ? 60 : tok->len), tok->text);
        return push_string(p, str_cap, tok->text, tok->len, err);
    }
    if (p->type == PN_PT_SPECTRUM) {
        if (tok->kind == PN_TOKEN_STRING) {
            if (p->num_count > 0)
                return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                    "parameter \"spectrum %s\" mixes numbers and strings", p->name);
            return push_string(p, str_cap, tok->text, tok->len, err);
        }
        if (p->str_count > 0)
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                "parameter \"spectrum %s\" mixes numbers and strings", p->name);
    }
    if (tok->kind == PN_TOKEN_STRING)
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                            "parameter \"%s %s\" expects numbers, found the string \"%s\"", tn, p->name, tok->text);
    double v;
    pn_status st = pn_token_number(tok, &v, err);
    if (st != PN_OK) return st;
    if (p->type == PN_PT_INTEGER && (v != floor(v) || v < (double)INT_MIN || v > (double)INT_MAX))
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                            "parameter \"integer %s\" expects integers, found \"%.*s\"", p->name,
                            (int)(tok->len > 60 ? 60 : tok->len), tok->text);
    return push_number(p, num_cap, v, err);
}

/* Splits "type name" (spaces or tabs around and between; nothing else). */
static pn_status parse_declaration(const pn_token *tok, pn_param *p, pn_err *err) {
    const char *s = tok->text, *end = tok->text + tok->len;
    while (s < end && (*s == ' ' || *s == '\t')) s++;
    const char *type_begin = s;
    while (s < end && *s != ' ' && *s != '\t') s++;
    const char *type_end = s;
    while (s < end && (*s == ' ' || *s == '\t')) s++;
    const char *name_begin = s;
    while (s < end && *s != ' ' && *s != '\t') s++;
    const char *name_end = s;
    while (s < end && (*s == ' ' || *s == '\t')) s++;
    if (type_begin == type_end || name_begin == name_end || s != end)
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                            "\"%s\" is not a parameter declaration of the form \"type name\"", tok->text);
    if (!lookup_type(type_begin, (size_t)(type_end - type_begin), &p->type))
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "unknown parameter type \"%.*s\" in \"%s\"",
                            (int)(type_end - type_begin), type_begin, tok->text);
    size_t n = (size_t)(name_end - name_begin);
    p->name = malloc(n + 1);
    if (!p->name) return oom(err);
    memcpy(p->name, name_begin, n);
    p->name[n] = '\0';
    return PN_OK;
}

static pn_status check_count(const pn_param *p, pn_err *err) {
    int k = 1;
    switch (p->type) {
    case PN_PT_POINT2:
    case PN_PT_VECTOR2: k = 2; break;
    case PN_PT_POINT3:
    case PN_PT_VECTOR3:
    case PN_PT_NORMAL3:
    case PN_PT_RGB: k = 3; break;
    default: break;
    }
    if (k > 1 && p->num_count % k != 0)
        return pn_param_error(p, err, "parameter \"%s %s\" has %d values, which is not a multiple of %d",
                              pn_param_type_name(p->type), p->name, p->num_count, k);
    if (p->type == PN_PT_SPECTRUM && p->num_count % 2 != 0)
        return pn_param_error(p, err, "parameter \"spectrum %s\" has %d values; (wavelength, value) pairs are needed",
                              p->name, p->num_count);
    return PN_OK;
}

pn_status pn_params_parse(pn_tokenizer *tz, pn_params *ps, pn_err *err) {
    for (;;) {
        pn_token tok;
        pn_status st = pn_tokenizer_peek(tz, &tok, err);
        if (st != PN_OK) return st;
        if (tok.kind != PN_TOKEN_STRING) return PN_OK;
        pn_tokenizer_next(tz, &tok, err);
        if (!pn_grow_for_append((void **)&ps->items, ps->count, sizeof *ps->items)) return oom(err);
        pn_param *p = &ps->items[ps->count];
        memset(p, 0, sizeof *p);
        p->loc = tok.loc;
        ps->count++; /* from here on pn_params_free releases whatever p holds */
        st = parse_declaration(&tok, p, err);
        if (st != PN_OK) return st;
        int num_cap = 0, str_cap = 0;
        pn_token v;
        st = pn_tokenizer_next(tz, &v, err);
        if (st != PN_OK) return st;
        if (v.kind == PN_TOKEN_LBRACKET) {
            pn_srcloc open = v.loc;
            for (;;) {
                st = pn_tokenizer_next(tz, &v, err);
                if (st != PN_OK) return st;
                if (v.kind == PN_TOKEN_RBRACKET) break;
                if (v.kind == PN_TOKEN_EOF)
                    return pn_loc_error(&open, PN_ERROR_BAD_INPUT, err,
                                        "the file ends inside the [ ] list of parameter \"%s %s\"",
                                        pn_param_type_name(p->type), p->name);
                if (v.kind == PN_TOKEN_LBRACKET)
                    return pn_loc_error(&v.loc, PN_ERROR_BAD_INPUT, err,
                                        "'[' inside the value list of parameter \"%s %s\"", pn_param_type_name(p->type),
                                        p->name);
                st = add_value(p, &v, &num_cap, &str_cap, err);
                if (st != PN_OK) return st;
            }
        } else if (v.kind == PN_TOKEN_STRING ||
                   (v.kind == PN_TOKEN_WORD && (pn_token_is_numeric(&v) || p->type == PN_PT_BOOL))) {
            st = add_value(p, &v, &num_cap, &str_cap, err);
            if (st != PN_OK) return st;
        } else {
            return pn_loc_error(&p->loc, PN_ERROR_BAD_INPUT, err, "parameter \"%s %s\" has no value",
                                pn_param_type_name(p->type), p->name);
        }
        st = check_count(p, err);
        if (st != PN_OK) return st;
    }
}

pn_status pn_params_append_copy(pn_params *ps, const pn_param *src, pn_err *err) {
    if (!pn_grow_for_append((void **)&ps->items, ps->count, sizeof *ps->items)) return oom(err);
    pn_param *p = &ps->items[ps->count];
    memset(p, 0, sizeof *p);
    p->type = src->type;
    p->loc = src->loc;
    ps->count++;
    p->name = strdup(src->name);
    if (!p->name) return oom(err);
    if (src->num_count > 0) {
        p->nums = malloc((size_t)src->num_count * sizeof *p->nums);
        if (!p->nums) return oom(err);
        memcpy(p->nums, src->nums, (size_t)src->num_count * sizeof *p->nums);
        p->num_count = src->num_count;
    }
    if (src->str_count > 0) {
        p->strs = calloc((size_t)src->str_count, sizeof *p->strs);
        if (!p->strs) return oom(err);
        for (int i = 0; i < src->str_count; i++) {
            p->strs[i] = strdup(src->strs[i]);
            if (!p->strs[i]) return oom(err);
            p->str_count = i + 1;
        }
    }
    return PN_OK;
}

/* ---- getters ----------------------------------------------------------------------------- */

static pn_status wrong_type(const pn_param *p, const char *expected, pn_err *err) {
    return pn_param_error(p, err, "parameter \"%s\" is declared \"%s\" but %s is expected here", p->name,
                          pn_param_type_name(p->type), expected);
}

static pn_status wrong_count(const pn_param *p, int expected, pn_err *err) {
    return pn_param_error(p, err, "parameter \"%s %s\" needs exactly %d value%s, found %d", pn_param_type_name(p->type),
                          p->name, expected, expected == 1 ? "" : "s",
                          p->type == PN_PT_STRING || p->type == PN_PT_TEXTURE ? p->str_count : p->num_count);
}

pn_status pn_params_float(const pn_params *ps, const char *name, double def, double *out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = def;
    if (!p) return PN_OK;
    if (p->type != PN_PT_FLOAT && p->type != PN_PT_INTEGER) return wrong_type(p, "a float", err);
    if (p->num_count != 1) return wrong_count(p, 1, err);
    *out = p->nums[0];
    return PN_OK;
}

pn_status pn_params_int(const pn_params *ps, const char *name, int def, int *out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = def;
    if (!p) return PN_OK;
    if (p->type != PN_PT_INTEGER) return wrong_type(p, "an integer", err);
    if (p->num_count != 1) return wrong_count(p, 1, err);
    *out = (int)p->nums[0];
    return PN_OK;
}

pn_status pn_params_bool(const pn_params *ps, const char *name, bool def, bool *out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = def;
    if (!p) return PN_OK;
    if (p->type != PN_PT_BOOL) return wrong_type(p, "a bool", err);
    if (p->num_count != 1) return wrong_count(p, 1, err);
    *out = p->nums[0] != 0.0;
    return PN_OK;
}

pn_status pn_params_string(const pn_params *ps, const char *name, const char *def, const char **out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = def;
    if (!p) return PN_OK;
    if (p->type != PN_PT_STRING) return wrong_type(p, "a string", err);
    if (p->str_count != 1) return wrong_count(p, 1, err);
    *out = p->strs[0];
    return PN_OK;
}

static bool is_triple_type(pn_param_type t) {
    return t == PN_PT_POINT3 || t == PN_PT_VECTOR3 || t == PN_PT_NORMAL3;
}

pn_status pn_params_vec3(const pn_params *ps, const char *name, vec3 def, vec3 *out, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = def;
    if (!p) return PN_OK;
    if (!is_triple_type(p->type)) return wrong_type(p, "a point3, vector3 or normal3", err);
    if (p->num_count != 3) return wrong_count(p, 3, err);
    *out = v3((float)p->nums[0], (float)p->nums[1], (float)p->nums[2]);
    return PN_OK;
}

static bool array_type_ok(pn_param_type want, pn_param_type have) {
    if (want == have) return true;
    switch (want) {
    case PN_PT_FLOAT: return have == PN_PT_INTEGER;
    case PN_PT_POINT2:
    case PN_PT_VECTOR2:
        /* pbrt-v3 files give texture coordinates as "float uv" */
        return have == PN_PT_POINT2 || have == PN_PT_VECTOR2 || have == PN_PT_FLOAT;
    case PN_PT_POINT3:
    case PN_PT_VECTOR3:
    case PN_PT_NORMAL3: return is_triple_type(have);
    default: return false;
    }
}

pn_status pn_params_array(const pn_params *ps, const char *name, pn_param_type type, int multiple_of,
                          const double **out, int *count, pn_err *err) {
    const pn_param *p = pn_params_find(ps, name);
    *out = NULL;
    *count = 0;
    if (!p) return PN_OK;
    if (!array_type_ok(type, p->type) || p->str_count > 0) {
        char expected[64];
        snprintf(expected, sizeof expected, "\"%s\" values", pn_param_type_name(type));
        return wrong_type(p, expected, err);
    }
    if (multiple_of > 1 && p->num_count % multiple_of != 0)
        return pn_param_error(p, err, "parameter \"%s %s\" has %d values, which is not a multiple of %d",
                              pn_param_type_name(p->type), p->name, p->num_count, multiple_of);
    *out = p->nums;
    *count = p->num_count;
    return PN_OK;
}

char *pn_path_resolve(const char *base_dir, const char *path) {
    if (!path) return NULL;
    if (path[0] == '/' || !base_dir || base_dir[0] == '\0') return strdup(path);
    size_t nb = strlen(base_dir), np = strlen(path);
    bool slash = base_dir[nb - 1] == '/';
    char *r = malloc(nb + np + 2);
    if (!r) return NULL;
    memcpy(r, base_dir, nb);
    size_t k = nb;
    if (!slash) r[k++] = '/';
    memcpy(r + k, path, np + 1);
    return r;
}

void pn_warn_at(struct pn_scene_s *scene, pn_srcloc loc, const char *fmt, ...) {
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    pn_scene_warn(scene, "%s:%d:%d: %s", loc.file ? loc.file : "?", loc.line, loc.column, msg);
}

char *pn_strdup(const char *s) {
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d) memcpy(d, s, n);
    return d;
}
