/* ply.c — PLY mesh reader: header parser, buffered body decoder (ascii and both binary byte
 * orders), triangulation of polygon faces, and validation of everything a file claims.
 *
 * The file is read through one growable buffer: the header is parsed line by line out of it and
 * the body is decoded straight from it, refilled with large fread calls. Every count in the
 * header is checked against the bytes actually left in the file before anything is allocated
 * for it, so a forged header cannot make the reader allocate or loop beyond the file's size. */
#include "scene/ply.h"

#include "core/file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define PLY_BUFFER_SIZE (512u << 10)
#define PLY_MAX_LINE 4096
#define PLY_MAX_TOKENS 8
#define PLY_MAX_NAME 128

typedef enum ply_type {
    PLY_NONE = 0,
    PLY_INT8,
    PLY_UINT8,
    PLY_INT16,
    PLY_UINT16,
    PLY_INT32,
    PLY_UINT32,
    PLY_FLOAT32,
    PLY_FLOAT64
} ply_type;

typedef enum ply_format { PLY_ASCII, PLY_BINARY_LE, PLY_BINARY_BE } ply_format;

/* Where a decoded property value goes. Vertex slots index the per-record value array. */
enum {
    SLOT_SKIP = -1,
    SLOT_X = 0,
    SLOT_Y,
    SLOT_Z,
    SLOT_NX,
    SLOT_NY,
    SLOT_NZ,
    SLOT_U,
    SLOT_V,
    SLOT_VERTEX_COUNT,
    SLOT_INDICES = 100
};

typedef enum ply_kind { KIND_OTHER, KIND_VERTEX, KIND_FACE } ply_kind;

typedef struct ply_prop {
    char name[PLY_MAX_NAME];
    ply_type type;       /* item type for lists */
    ply_type count_type; /* PLY_NONE for scalar properties */
    int slot;
} ply_prop;

typedef struct ply_elem {
    char name[PLY_MAX_NAME];
    uint64_t count;
    ply_kind kind;
    ply_prop *props;
    size_t prop_count, prop_cap;
    size_t fixed_size; /* binary bytes of one record when it has no lists, else 0 */
    bool has_lists;
} ply_elem;

typedef struct ply_reader {
    const char *path;
    pn_err *err;
    FILE *fp;
    unsigned char *buf;
    size_t cap, pos, len;
    uint64_t buf_offset; /* file offset of buf[0] */
    uint64_t file_size;
    bool io_failed;
    ply_format format;
    bool swap;     /* binary body in the other byte order than the host */
    uint64_t line; /* current line (header, and ascii body) */
    ply_elem *elems;
    size_t elem_count, elem_cap;
    uint64_t vertex_count; /* from the header, 0 without a vertex element */
    /* mesh under construction */
    pn_ply_mesh mesh;
    size_t tri_cap;
    uint32_t *face; /* indices of the face being read */
    size_t face_cap;
    bool want_normals, want_uvs; /* the vertex element has all the properties for them */
} ply_reader;

static const struct {
    const char *name;
    ply_type type;
} ply_type_names[] = {
    {"char", PLY_INT8},     {"int8", PLY_INT8},       {"uchar", PLY_UINT8},    {"uint8", PLY_UINT8},
    {"short", PLY_INT16},   {"int16", PLY_INT16},     {"ushort", PLY_UINT16},  {"uint16", PLY_UINT16},
    {"int", PLY_INT32},     {"int32", PLY_INT32},     {"uint", PLY_UINT32},    {"uint32", PLY_UINT32},
    {"float", PLY_FLOAT32}, {"float32", PLY_FLOAT32}, {"double", PLY_FLOAT64}, {"float64", PLY_FLOAT64},
};

static size_t ply_type_size(ply_type t) {
    switch (t) {
    case PLY_INT8:
    case PLY_UINT8: return 1;
    case PLY_INT16:
    case PLY_UINT16: return 2;
    case PLY_INT32:
    case PLY_UINT32:
    case PLY_FLOAT32: return 4;
    case PLY_FLOAT64: return 8;
    case PLY_NONE: break;
    }
    return 0;
}

static ply_type ply_type_from_name(const char *name) {
    for (size_t i = 0; i < sizeof ply_type_names / sizeof ply_type_names[0]; i++)
        if (strcmp(ply_type_names[i].name, name) == 0) return ply_type_names[i].type;
    return PLY_NONE;
}

static bool ply_type_is_integer(ply_type t) {
    return t != PLY_FLOAT32 && t != PLY_FLOAT64;
}

/* ---- errors ---------------------------------------------------------------------------- */

static pn_status ply_fail(ply_reader *r, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static pn_status ply_fail(ply_reader *r, const char *fmt, ...) {
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return pn_err_set(r->err, PN_ERROR_BAD_INPUT, "%s: %s", r->path, msg);
}

static pn_status ply_fail_io(ply_reader *r, int errnum) {
    return pn_err_set(r->err, PN_ERROR_IO, "%s: %s", r->path, strerror(errnum ? errnum : EIO));
}

/* English plural of an element name for messages: "vertices", "faces", "edges". */
static const char *ply_plural(const ply_elem *e, char *out, size_t size) {
    if (strcmp(e->name, "vertex") == 0) return "vertices";
    snprintf(out, size, "%ss", e->name);
    return out;
}

/* ---- buffered input -------------------------------------------------------------------- */

static uint64_t ply_remaining(const ply_reader *r) {
    uint64_t at = r->buf_offset + r->pos;
    return at < r->file_size ? r->file_size - at : 0;
}

/* Moves unread bytes to the front and appends what fread gives; returns the bytes added. */
static size_t ply_fill(ply_reader *r) {
    if (r->pos > 0) {
        memmove(r->buf, r->buf + r->pos, r->len - r->pos);
        r->buf_offset += r->pos;
        r->len -= r->pos;
        r->pos = 0;
    }
    if (r->len == r->cap || r->io_failed) return 0;
    size_t got = fread(r->buf + r->len, 1, r->cap - r->len, r->fp);
    if (got == 0 && ferror(r->fp)) {
        r->io_failed = true;
        ply_fail_io(r, errno);
    }
    r->len += got;
    return got;
}

/* Makes n bytes available at buf + pos; false if the file ends (or a read fails) first. The
 * buffer grows when n exceeds it, but only after n is known to fit in the rest of the file. */
static bool ply_ensure(ply_reader *r, size_t n) {
    if (r->len - r->pos >= n) return true;
    if ((uint64_t)n > ply_remaining(r)) return false;
    if (n > r->cap) {
        size_t cap = r->cap * 2 > n ? r->cap * 2 : n;
        unsigned char *grown = realloc(r->buf, cap);
        if (grown == NULL) {
            pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
            r->io_failed = true;
            return false;
        }
        r->buf = grown;
        r->cap = cap;
    }
    while (r->len - r->pos < n)
        if (ply_fill(r) == 0) return false;
    return true;
}

/* Consumes n bytes without looking at them; false if the file ends first. */
static bool ply_skip(ply_reader *r, uint64_t n) {
    if (n > ply_remaining(r)) return false;
    while (n > 0) {
        size_t have = r->len - r->pos;
        if (have == 0) {
            if (ply_fill(r) == 0) return false;
            continue;
        }
        size_t take = (uint64_t)have < n ? have : (size_t)n;
        r->pos += take;
        n -= take;
    }
    return true;
}

/* ---- header ---------------------------------------------------------------------------- */

/* Copies the next header line (without \r\n) into line; false at end of file or on error. */
static bool ply_read_line(ply_reader *r, char *line, size_t size) {
    for (;;) {
        unsigned char *start = r->buf + r->pos;
        unsigned char *nl = memchr(start, '\n', r->len - r->pos);
        if (nl != NULL) {
            size_t n = (size_t)(nl - start);
            r->pos += n + 1;
            r->line++;
            if (n > 0 && start[n - 1] == '\r') n--;
            if (n >= size) {
                ply_fail(r, "header: line %llu is too long", (unsigned long long)r->line);
                return false;
            }
            memcpy(line, start, n);
            line[n] = '\0';
            return true;
        }
        if (r->len - r->pos >= size) {
            ply_fail(r, "header: line %llu is too long", (unsigned long long)r->line + 1);
            return false;
        }
        if (ply_fill(r) == 0) {
            ply_fail(r, "header: file ends before end_header");
            return false;
        }
    }
}

/* Splits line at spaces and tabs; returns the number of tokens (at most max). */
static size_t ply_split(char *line, char **tokens, size_t max) {
    size_t n = 0;
    char *p = line;
    for (;;) {
        while (*p == ' ' || *p == '\t') p++;
        if (*p == '\0' || n == max) break;
        tokens[n++] = p;
        while (*p != '\0' && *p != ' ' && *p != '\t') p++;
        if (*p == '\0') break;
        *p++ = '\0';
    }
    return n;
}

static bool ply_parse_count(const char *s, uint64_t *out) {
    if (*s < '0' || *s > '9') return false;
    uint64_t v = 0;
    for (; *s; s++) {
        if (*s < '0' || *s > '9') return false;
        uint64_t digit = (uint64_t)(*s - '0');
        if (v > (UINT64_MAX - digit) / 10) return false;
        v = v * 10 + digit;
    }
    *out = v;
    return true;
}

static ply_elem *ply_find_elem(ply_reader *r, const char *name) {
    for (size_t i = 0; i < r->elem_count; i++)
        if (strcmp(r->elems[i].name, name) == 0) return &r->elems[i];
    return NULL;
}

static int ply_vertex_slot(const char *name) {
    static const struct {
        const char *name;
        int slot;
    } names[] = {
        {"x", SLOT_X},         {"y", SLOT_Y},         {"z", SLOT_Z},         {"nx", SLOT_NX},
        {"ny", SLOT_NY},       {"nz", SLOT_NZ},       {"normal_x", SLOT_NX}, {"normal_y", SLOT_NY},
        {"normal_z", SLOT_NZ}, {"u", SLOT_U},         {"v", SLOT_V},         {"s", SLOT_U},
        {"t", SLOT_V},         {"texture_u", SLOT_U}, {"texture_v", SLOT_V}, {"texture_s", SLOT_U},
        {"texture_t", SLOT_V},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (strcmp(names[i].name, name) == 0) return names[i].slot;
    return SLOT_SKIP;
}

/* The texture-coordinate pair a property name belongs to (0 for none). */
static int ply_uv_family(const char *name) {
    if (!strcmp(name, "u") || !strcmp(name, "v")) return 1;
    if (!strcmp(name, "s") || !strcmp(name, "t")) return 2;
    if (!strcmp(name, "texture_u") || !strcmp(name, "texture_v")) return 3;
    if (!strcmp(name, "texture_s") || !strcmp(name, "texture_t")) return 4;
    return 0;
}

/* Decides which vertex and face properties are used once the whole header is known. */
static pn_status ply_assign_slots(ply_reader *r) {
    for (size_t i = 0; i < r->elem_count; i++) {
        ply_elem *e = &r->elems[i];
        for (size_t j = 0; j < e->prop_count; j++) e->props[j].slot = SLOT_SKIP;
        if (e->kind == KIND_FACE) {
            for (size_t j = 0; j < e->prop_count; j++) {
                ply_prop *p = &e->props[j];
                if (strcmp(p->name, "vertex_indices") != 0 && strcmp(p->name, "vertex_index") != 0) continue;
                if (p->count_type == PLY_NONE) return ply_fail(r, "header: face property '%s' is not a list", p->name);
                p->slot = SLOT_INDICES;
                break;
            }
            bool found = false;
            for (size_t j = 0; j < e->prop_count; j++) found |= e->props[j].slot == SLOT_INDICES;
            if (!found) return ply_fail(r, "header: the face element has no vertex_indices list");
        } else if (e->kind == KIND_VERTEX) {
            int uv_family = 0;
            int where[SLOT_VERTEX_COUNT];
            for (int s = 0; s < SLOT_VERTEX_COUNT; s++) where[s] = -1;
            for (size_t j = 0; j < e->prop_count; j++) {
                ply_prop *p = &e->props[j];
                int slot = ply_vertex_slot(p->name);
                if (slot == SLOT_SKIP) continue;
                if (slot == SLOT_U || slot == SLOT_V) {
                    int fam = ply_uv_family(p->name);
                    if (uv_family == 0) uv_family = fam;
                    if (fam != uv_family) continue;
                }
                if (where[slot] >= 0) continue; /* e.g. both nx and normal_x: first wins */
                if (p->count_type != PLY_NONE)
                    return ply_fail(r, "header: vertex property '%s' must not be a list", p->name);
                where[slot] = (int)j;
            }
            if (where[SLOT_X] < 0 || where[SLOT_Y] < 0 || where[SLOT_Z] < 0)
                return ply_fail(r, "header: the vertex element lacks one of x, y, z");
            bool normals = where[SLOT_NX] >= 0 && where[SLOT_NY] >= 0 && where[SLOT_NZ] >= 0;
            bool uvs = where[SLOT_U] >= 0 && where[SLOT_V] >= 0;
            for (int s = 0; s < SLOT_VERTEX_COUNT; s++) {
                if (where[s] < 0) continue;
                if (!normals && s >= SLOT_NX && s <= SLOT_NZ) continue;
                if (!uvs && s >= SLOT_U) continue;
                e->props[where[s]].slot = s;
            }
            r->want_normals = normals;
            r->want_uvs = uvs;
        }
    }
    return PN_OK;
}

static pn_status ply_parse_header(ply_reader *r) {
    /* Identify the file from its first bytes before treating anything as text. */
    if (!ply_ensure(r, 2) && r->io_failed) return r->err->status;
    if (r->len - r->pos >= 2 && r->buf[0] == 0x1f && r->buf[1] == 0x8b)
        return ply_fail(r, "gzip-compressed PLY files are not supported; decompress it first");
    if (!ply_ensure(r, 4) || memcmp(r->buf, "ply", 3) != 0 || (r->buf[3] != '\n' && r->buf[3] != '\r')) {
        if (r->io_failed) return r->err->status;
        return ply_fail(r, "not a PLY file");
    }

    char line[PLY_MAX_LINE];
    char *tok[PLY_MAX_TOKENS];
    bool have_format = false;
    if (!ply_read_line(r, line, sizeof line)) return r->err->status;
    if (strcmp(line, "ply") != 0) return ply_fail(r, "not a PLY file");

    for (;;) {
        if (!ply_read_line(r, line, sizeof line)) return r->err->status;
        unsigned long long ln = (unsigned long long)r->line;
        size_t n = ply_split(line, tok, PLY_MAX_TOKENS);
        if (n == 0) continue;
        if (!strcmp(tok[0], "comment") || !strcmp(tok[0], "obj_info")) continue;
        if (!strcmp(tok[0], "end_header")) break;
        if (!strcmp(tok[0], "format")) {
            if (have_format) return ply_fail(r, "header: second format line on line %llu", ln);
            if (n != 3) return ply_fail(r, "header: malformed format line on line %llu", ln);
            if (!strcmp(tok[1], "ascii"))
                r->format = PLY_ASCII;
            else if (!strcmp(tok[1], "binary_little_endian"))
                r->format = PLY_BINARY_LE;
            else if (!strcmp(tok[1], "binary_big_endian"))
                r->format = PLY_BINARY_BE;
            else
                return ply_fail(r, "header: unknown format '%s' on line %llu", tok[1], ln);
            if (strcmp(tok[2], "1.0") != 0 && strcmp(tok[2], "1") != 0)
                return ply_fail(r, "header: unsupported version '%s' on line %llu", tok[2], ln);
            have_format = true;
        } else if (!strcmp(tok[0], "element")) {
            uint64_t count;
            if (n != 3) return ply_fail(r, "header: malformed element line on line %llu", ln);
            if (!ply_parse_count(tok[2], &count))
                return ply_fail(r, "header: bad element count '%s' on line %llu", tok[2], ln);
            if (strlen(tok[1]) >= PLY_MAX_NAME) return ply_fail(r, "header: element name too long on line %llu", ln);
            if (ply_find_elem(r, tok[1]) != NULL)
                return ply_fail(r, "header: second element '%s' on line %llu", tok[1], ln);
            if (r->elem_count == r->elem_cap) {
                size_t cap = r->elem_cap ? r->elem_cap * 2 : 4;
                ply_elem *grown = realloc(r->elems, cap * sizeof *grown);
                if (grown == NULL) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
                r->elems = grown;
                r->elem_cap = cap;
            }
            ply_elem *e = &r->elems[r->elem_count++];
            memset(e, 0, sizeof *e);
            snprintf(e->name, sizeof e->name, "%s", tok[1]);
            e->count = count;
            e->kind = !strcmp(e->name, "vertex") ? KIND_VERTEX : !strcmp(e->name, "face") ? KIND_FACE : KIND_OTHER;
            if (e->kind == KIND_VERTEX) {
                if (count > UINT32_MAX)
                    return ply_fail(r, "header: %llu vertices is more than supported, on line %llu",
                                    (unsigned long long)count, ln);
                r->vertex_count = count;
            }
        } else if (!strcmp(tok[0], "property")) {
            if (r->elem_count == 0) return ply_fail(r, "header: property before any element on line %llu", ln);
            ply_elem *e = &r->elems[r->elem_count - 1];
            ply_prop p;
            memset(&p, 0, sizeof p);
            const char *name;
            if (n >= 2 && !strcmp(tok[1], "list")) {
                if (n != 5) return ply_fail(r, "header: malformed list property on line %llu", ln);
                p.count_type = ply_type_from_name(tok[2]);
                p.type = ply_type_from_name(tok[3]);
                if (p.count_type == PLY_NONE)
                    return ply_fail(r, "header: unknown property type '%s' on line %llu", tok[2], ln);
                if (p.type == PLY_NONE)
                    return ply_fail(r, "header: unknown property type '%s' on line %llu", tok[3], ln);
                if (!ply_type_is_integer(p.count_type))
                    return ply_fail(r, "header: list count type '%s' is not an integer type on line %llu", tok[2], ln);
                name = tok[4];
            } else {
                if (n != 3) return ply_fail(r, "header: malformed property line on line %llu", ln);
                p.type = ply_type_from_name(tok[1]);
                if (p.type == PLY_NONE)
                    return ply_fail(r, "header: unknown property type '%s' on line %llu", tok[1], ln);
                name = tok[2];
            }
            if (strlen(name) >= PLY_MAX_NAME) return ply_fail(r, "header: property name too long on line %llu", ln);
            for (size_t i = 0; i < e->prop_count; i++)
                if (!strcmp(e->props[i].name, name))
                    return ply_fail(r, "header: second property '%s' in element '%s' on line %llu", name, e->name, ln);
            snprintf(p.name, sizeof p.name, "%s", name);
            if (e->prop_count == e->prop_cap) {
                size_t cap = e->prop_cap ? e->prop_cap * 2 : 8;
                ply_prop *grown = realloc(e->props, cap * sizeof *grown);
                if (grown == NULL) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
                e->props = grown;
                e->prop_cap = cap;
            }
            e->props[e->prop_count++] = p;
            if (p.count_type != PLY_NONE) e->has_lists = true;
        } else {
            return ply_fail(r, "header: unknown keyword '%s' on line %llu", tok[0], ln);
        }
    }
    if (!have_format) return ply_fail(r, "header: no format line");
    if (ply_find_elem(r, "vertex") == NULL) return ply_fail(r, "header: no vertex element");

    for (size_t i = 0; i < r->elem_count; i++) {
        ply_elem *e = &r->elems[i];
        size_t size = 0;
        for (size_t j = 0; j < e->prop_count; j++)
            if (e->props[j].count_type == PLY_NONE) size += ply_type_size(e->props[j].type);
        e->fixed_size = e->has_lists ? 0 : size;
    }
    return ply_assign_slots(r);
}

/* Checks that the body can hold every record the header declares, counting the fewest bytes a
 * record can take (lists empty; in ascii one character plus a separator per value). */
static pn_status ply_check_sizes(ply_reader *r) {
    uint64_t remaining = ply_remaining(r);
    uint64_t needed = 0;
    bool exact = true; /* all elements so far have fixed-size binary records */
    for (size_t i = 0; i < r->elem_count; i++) {
        ply_elem *e = &r->elems[i];
        uint64_t min_record = 0;
        for (size_t j = 0; j < e->prop_count; j++) {
            const ply_prop *p = &e->props[j];
            if (r->format == PLY_ASCII)
                min_record += 2;
            else
                min_record += ply_type_size(p->count_type != PLY_NONE ? p->count_type : p->type);
        }
        if (r->format == PLY_ASCII || e->has_lists) exact = false;
        if (min_record == 0) continue; /* records without properties occupy nothing */
        uint64_t room = remaining - needed + (r->format == PLY_ASCII ? 1 : 0);
        if (e->count > room / min_record) {
            char plural[PLY_MAX_NAME + 2];
            const char *what = ply_plural(e, plural, sizeof plural);
            if (exact)
                return ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)(room / min_record),
                                (unsigned long long)e->count, what);
            return ply_fail(r, "file is too short for the %llu %s its header declares", (unsigned long long)e->count,
                            what);
        }
        needed += e->count * min_record;
        if (needed > remaining) needed = remaining;
    }
    return PN_OK;
}

/* ---- value decoding -------------------------------------------------------------------- */

static inline double ply_load(const unsigned char *p, ply_type t, bool swap) {
    unsigned char b[8];
    size_t n = ply_type_size(t);
    if (swap) {
        for (size_t i = 0; i < n; i++) b[i] = p[n - 1 - i];
        p = b;
    }
    switch (t) {
    case PLY_INT8: return (double)(int8_t)p[0];
    case PLY_UINT8: return (double)p[0];
    case PLY_INT16: {
        int16_t v;
        memcpy(&v, p, 2);
        return (double)v;
    }
    case PLY_UINT16: {
        uint16_t v;
        memcpy(&v, p, 2);
        return (double)v;
    }
    case PLY_INT32: {
        int32_t v;
        memcpy(&v, p, 4);
        return (double)v;
    }
    case PLY_UINT32: {
        uint32_t v;
        memcpy(&v, p, 4);
        return (double)v;
    }
    case PLY_FLOAT32: {
        float v;
        memcpy(&v, p, 4);
        return (double)v;
    }
    case PLY_FLOAT64: {
        double v;
        memcpy(&v, p, 8);
        return v;
    }
    case PLY_NONE: break;
    }
    return 0.0;
}

/* Reads one whitespace-separated ascii token into tok; false at end of file (or error). */
static bool ply_ascii_token(ply_reader *r, char *tok, size_t size) {
    for (;;) { /* skip whitespace */
        if (r->pos == r->len && ply_fill(r) == 0) return false;
        unsigned char c = r->buf[r->pos];
        if (c == '\n')
            r->line++;
        else if (c != ' ' && c != '\t' && c != '\r' && c != '\f' && c != '\v')
            break;
        r->pos++;
    }
    size_t n = 0;
    for (;;) {
        if (r->pos == r->len && ply_fill(r) == 0) break;
        unsigned char c = r->buf[r->pos];
        if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v') break;
        if (n + 1 >= size) {
            ply_fail(r, "line %llu: value too long", (unsigned long long)r->line);
            r->io_failed = true;
            return false;
        }
        tok[n++] = (char)c;
        r->pos++;
    }
    tok[n] = '\0';
    return !r->io_failed;
}

/* Reads one value of type t from the body (either format). On failure records an error naming
 * the property, the record and the element, and returns false. */
static bool ply_read_value(ply_reader *r, ply_type t, double *out, const ply_elem *e, uint64_t record,
                           const char *prop) {
    char plural[PLY_MAX_NAME + 2];
    if (r->format != PLY_ASCII) {
        size_t n = ply_type_size(t);
        if (!ply_ensure(r, n)) {
            if (r->err->status == PN_OK)
                ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)record, (unsigned long long)e->count,
                         ply_plural(e, plural, sizeof plural));
            return false;
        }
        *out = ply_load(r->buf + r->pos, t, r->swap);
        r->pos += n;
        return true;
    }
    char tok[128];
    if (!ply_ascii_token(r, tok, sizeof tok)) {
        if (r->err->status == PN_OK)
            ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)record, (unsigned long long)e->count,
                     ply_plural(e, plural, sizeof plural));
        return false;
    }
    char *end;
    double v = strtod(tok, &end);
    if (end == tok || *end != '\0') {
        ply_fail(r, "line %llu: '%s' is not a number (property '%s' of %s %llu)", (unsigned long long)r->line, tok,
                 prop, e->name, (unsigned long long)record);
        return false;
    }
    if (ply_type_is_integer(t) && v != floor(v)) {
        ply_fail(r, "line %llu: '%s' is not an integer (property '%s' of %s %llu)", (unsigned long long)r->line, tok,
                 prop, e->name, (unsigned long long)record);
        return false;
    }
    *out = v;
    return true;
}

/* ---- records --------------------------------------------------------------------------- */

static bool ply_push_triangle(ply_reader *r, uint32_t a, uint32_t b, uint32_t c) {
    pn_ply_mesh *m = &r->mesh;
    if (m->triangle_count == r->tri_cap) {
        if (m->triangle_count == UINT32_MAX) {
            ply_fail(r, "more than %u triangles", (unsigned)UINT32_MAX);
            return false;
        }
        size_t cap = r->tri_cap < 1024 ? 1024 : r->tri_cap * 2;
        if (cap > UINT32_MAX) cap = UINT32_MAX;
        uint32_t *grown = realloc(m->indices, cap * 3 * sizeof *grown);
        if (grown == NULL) {
            pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
            return false;
        }
        m->indices = grown;
        r->tri_cap = cap;
    }
    uint32_t *t = m->indices + 3 * (size_t)m->triangle_count++;
    t[0] = a;
    t[1] = b;
    t[2] = c;
    return true;
}

/* Reads a list property; its items go to the face buffer when used, else are discarded.
 * *item_count receives the list length. */
static bool ply_read_list(ply_reader *r, const ply_elem *e, const ply_prop *p, uint64_t record, size_t *item_count) {
    double cv;
    if (!ply_read_value(r, p->count_type, &cv, e, record, p->name)) return false;
    if (cv < 0) {
        ply_fail(r, "%s %llu: negative list length %.0f for '%s'", e->name, (unsigned long long)record, cv, p->name);
        return false;
    }
    if (cv > (double)UINT32_MAX) {
        ply_fail(r, "%s %llu: list length %.0f for '%s' is too large", e->name, (unsigned long long)record, cv,
                 p->name);
        return false;
    }
    size_t count = (size_t)cv;
    *item_count = count;
    size_t item = ply_type_size(p->type);
    char plural[PLY_MAX_NAME + 2];

    if (p->slot != SLOT_INDICES) {
        if (r->format != PLY_ASCII) {
            if (!ply_skip(r, (uint64_t)count * item)) {
                if (r->err->status == PN_OK)
                    ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)record,
                             (unsigned long long)e->count, ply_plural(e, plural, sizeof plural));
                return false;
            }
            return true;
        }
        for (size_t i = 0; i < count; i++) {
            double v;
            if (!ply_read_value(r, p->type, &v, e, record, p->name)) return false;
        }
        return true;
    }

    if (r->format != PLY_ASCII) {
        /* Bring the whole list in at once: the check against the file size comes first, so a
         * forged length cannot make the buffer grow past the file. */
        if (!ply_ensure(r, count * item)) {
            if (r->err->status == PN_OK)
                ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)record, (unsigned long long)e->count,
                         ply_plural(e, plural, sizeof plural));
            return false;
        }
    } else if ((uint64_t)count > (ply_remaining(r) + 1) / 2) {
        /* Each ascii item takes at least a digit and a separator. */
        ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)record, (unsigned long long)e->count,
                 ply_plural(e, plural, sizeof plural));
        return false;
    }
    if (count > r->face_cap) {
        size_t cap = r->face_cap ? r->face_cap : 16;
        while (cap < count) cap *= 2;
        uint32_t *grown = realloc(r->face, cap * sizeof *grown);
        if (grown == NULL) {
            pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
            return false;
        }
        r->face = grown;
        r->face_cap = cap;
    }
    for (size_t i = 0; i < count; i++) {
        double v;
        if (r->format != PLY_ASCII) {
            v = ply_load(r->buf + r->pos, p->type, r->swap);
            r->pos += item;
        } else if (!ply_read_value(r, p->type, &v, e, record, p->name)) {
            return false;
        }
        if (!(v >= 0 && v < (double)r->vertex_count) || v != floor(v)) {
            ply_fail(r, "face %llu refers to vertex %.17g but there are %llu vertices", (unsigned long long)record, v,
                     (unsigned long long)r->vertex_count);
            return false;
        }
        r->face[i] = (uint32_t)v;
    }
    return true;
}

static bool ply_store_vertex(ply_reader *r, uint64_t index, const double *v) {
    pn_ply_mesh *m = &r->mesh;
    float *p = m->positions + 3 * index;
    p[0] = (float)v[SLOT_X];
    p[1] = (float)v[SLOT_Y];
    p[2] = (float)v[SLOT_Z];
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2])) {
        ply_fail(r, "vertex %llu has a position that is not a finite number", (unsigned long long)index);
        return false;
    }
    if (m->normals != NULL) {
        float *n = m->normals + 3 * index;
        n[0] = (float)v[SLOT_NX];
        n[1] = (float)v[SLOT_NY];
        n[2] = (float)v[SLOT_NZ];
    }
    if (m->uvs != NULL) {
        float *t = m->uvs + 2 * index;
        t[0] = (float)v[SLOT_U];
        t[1] = (float)v[SLOT_V];
        if (!isfinite(t[0]) || !isfinite(t[1])) {
            ply_fail(r, "vertex %llu has a texture coordinate that is not a finite number", (unsigned long long)index);
            return false;
        }
    }
    return true;
}

/* Reads one record property by property (both formats, any layout). */
static bool ply_read_record(ply_reader *r, const ply_elem *e, uint64_t i, double *vals) {
    size_t face_len = 0;
    bool have_face = false;
    for (size_t j = 0; j < e->prop_count; j++) {
        const ply_prop *p = &e->props[j];
        if (p->count_type != PLY_NONE) {
            size_t len;
            if (!ply_read_list(r, e, p, i, &len)) return false;
            if (p->slot == SLOT_INDICES) {
                face_len = len;
                have_face = true;
            }
        } else {
            double v;
            if (!ply_read_value(r, p->type, &v, e, i, p->name)) return false;
            if (e->kind == KIND_VERTEX && p->slot != SLOT_SKIP) vals[p->slot] = v;
        }
    }
    if (e->kind == KIND_VERTEX) return ply_store_vertex(r, i, vals);
    if (!have_face) return true;
    if (face_len < 3) {
        r->mesh.skipped_face_count++;
        return true;
    }
    for (size_t k = 1; k + 1 < face_len; k++)
        if (!ply_push_triangle(r, r->face[0], r->face[k], r->face[k + 1])) return false;
    return true;
}

/* Binary vertices without lists: one buffer check per record, then only the used properties
 * are decoded, straight from the buffer. */
static pn_status ply_read_binary_vertices(ply_reader *r, const ply_elem *e) {
    double vals[SLOT_VERTEX_COUNT] = {0};
    size_t offset[SLOT_VERTEX_COUNT];
    ply_type type[SLOT_VERTEX_COUNT];
    int slots[SLOT_VERTEX_COUNT];
    size_t used = 0, at = 0;
    bool all_native_float = !r->swap;
    for (size_t j = 0; j < e->prop_count; j++) {
        const ply_prop *p = &e->props[j];
        if (p->slot != SLOT_SKIP) {
            slots[used] = p->slot;
            offset[used] = at;
            type[used] = p->type;
            if (p->type != PLY_FLOAT32) all_native_float = false;
            used++;
        }
        at += ply_type_size(p->type);
    }
    for (uint64_t i = 0; i < e->count; i++) {
        if (!ply_ensure(r, e->fixed_size)) {
            if (r->err->status != PN_OK) return r->err->status;
            return ply_fail(r, "file ends after %llu of %llu vertices", (unsigned long long)i,
                            (unsigned long long)e->count);
        }
        const unsigned char *rec = r->buf + r->pos;
        if (all_native_float) {
            for (size_t k = 0; k < used; k++) {
                float f;
                memcpy(&f, rec + offset[k], sizeof f);
                vals[slots[k]] = (double)f;
            }
        } else {
            for (size_t k = 0; k < used; k++) vals[slots[k]] = ply_load(rec + offset[k], type[k], r->swap);
        }
        r->pos += e->fixed_size;
        if (!ply_store_vertex(r, i, vals)) return r->err->status;
    }
    return PN_OK;
}

/* Loads an integer-typed value as a signed 64-bit number. */
static inline int64_t ply_load_int(const unsigned char *p, ply_type t, bool swap) {
    unsigned char b[4];
    size_t n = ply_type_size(t);
    if (swap) {
        for (size_t i = 0; i < n; i++) b[i] = p[n - 1 - i];
        p = b;
    }
    switch (t) {
    case PLY_INT8: return (int8_t)p[0];
    case PLY_UINT8: return p[0];
    case PLY_INT16: {
        int16_t v;
        memcpy(&v, p, 2);
        return v;
    }
    case PLY_UINT16: {
        uint16_t v;
        memcpy(&v, p, 2);
        return v;
    }
    case PLY_INT32: {
        int32_t v;
        memcpy(&v, p, 4);
        return v;
    }
    case PLY_UINT32: {
        uint32_t v;
        memcpy(&v, p, 4);
        return v;
    }
    default: break;
    }
    return -1;
}

/* Binary faces whose only list is an integer index list: triangles are decoded in place; any
 * other record (a polygon, a short file, a bad index) goes through ply_read_record, which
 * handles it in full and words the error. */
static pn_status ply_read_binary_faces(ply_reader *r, const ply_elem *e, size_t list_at) {
    const ply_prop *lp = &e->props[list_at];
    size_t before = 0, after = 0;
    for (size_t j = 0; j < e->prop_count; j++) {
        if (j == list_at) continue;
        size_t size = ply_type_size(e->props[j].type);
        if (j < list_at)
            before += size;
        else
            after += size;
    }
    size_t count_size = ply_type_size(lp->count_type), item = ply_type_size(lp->type);
    size_t tri_size = before + count_size + 3 * item + after;
    int64_t nv = (int64_t)r->vertex_count;
    double unused[SLOT_VERTEX_COUNT] = {0};
    for (uint64_t i = 0; i < e->count; i++) {
        if (ply_ensure(r, tri_size)) {
            const unsigned char *rec = r->buf + r->pos + before;
            if (ply_load_int(rec, lp->count_type, r->swap) == 3) {
                rec += count_size;
                int64_t a = ply_load_int(rec, lp->type, r->swap);
                int64_t b = ply_load_int(rec + item, lp->type, r->swap);
                int64_t c = ply_load_int(rec + 2 * item, lp->type, r->swap);
                if (a >= 0 && a < nv && b >= 0 && b < nv && c >= 0 && c < nv) {
                    if (!ply_push_triangle(r, (uint32_t)a, (uint32_t)b, (uint32_t)c)) return r->err->status;
                    r->pos += tri_size;
                    continue;
                }
            }
        } else if (r->err->status != PN_OK) {
            return r->err->status;
        }
        if (!ply_read_record(r, e, i, unused)) return r->err->status;
    }
    return PN_OK;
}

static pn_status ply_read_element(ply_reader *r, const ply_elem *e) {
    double vals[SLOT_VERTEX_COUNT] = {0};
    char plural[PLY_MAX_NAME + 2];

    if (e->prop_count == 0 || e->count == 0) return PN_OK;

    if (r->format != PLY_ASCII) {
        /* Elements of no interest with fixed-size records are stepped over in one go. */
        if (e->kind == KIND_OTHER && !e->has_lists) {
            if (!ply_skip(r, e->count * e->fixed_size)) {
                if (r->err->status != PN_OK) return r->err->status;
                uint64_t done = ply_remaining(r) / e->fixed_size;
                return ply_fail(r, "file ends after %llu of %llu %s", (unsigned long long)done,
                                (unsigned long long)e->count, ply_plural(e, plural, sizeof plural));
            }
            return PN_OK;
        }
        if (e->kind == KIND_VERTEX && !e->has_lists) return ply_read_binary_vertices(r, e);
        if (e->kind == KIND_FACE) {
            size_t lists = 0, list_at = 0;
            for (size_t j = 0; j < e->prop_count; j++) {
                if (e->props[j].count_type == PLY_NONE) continue;
                lists++;
                list_at = j;
            }
            if (lists == 1 && e->props[list_at].slot == SLOT_INDICES && ply_type_is_integer(e->props[list_at].type))
                return ply_read_binary_faces(r, e, list_at);
        }
    }

    for (uint64_t i = 0; i < e->count; i++)
        if (!ply_read_record(r, e, i, vals)) return r->err->status;
    return PN_OK;
}

/* Normalises the normals, or drops them all if any cannot be normalised. */
static void ply_finish_normals(ply_reader *r) {
    pn_ply_mesh *m = &r->mesh;
    if (m->normals == NULL) return;
    for (size_t i = 0; i < m->vertex_count; i++) {
        float *n = m->normals + 3 * i;
        double x = (double)n[0], y = (double)n[1], z = (double)n[2];
        double len = sqrt(x * x + y * y + z * z);
        if (!(len > 0.0) || !isfinite(len)) {
            free(m->normals);
            m->normals = NULL;
            return;
        }
        n[0] = (float)(x / len);
        n[1] = (float)(y / len);
        n[2] = (float)(z / len);
    }
}

/* ---- entry points ---------------------------------------------------------------------- */

static pn_status ply_read_all(ply_reader *r) {
    pn_status st = ply_parse_header(r);
    if (st != PN_OK) return st;
    r->line++; /* from here on, the number of the line being read */
    bool host_big = __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__;
    r->swap = (r->format == PLY_BINARY_BE) != host_big && r->format != PLY_ASCII;
    if ((st = ply_check_sizes(r)) != PN_OK) return st;

    pn_ply_mesh *m = &r->mesh;
    bool want_normals = r->want_normals, want_uvs = r->want_uvs;
    size_t nv = (size_t)r->vertex_count;
    m->vertex_count = (uint32_t)nv;
    m->positions = malloc((nv ? nv : 1) * 3 * sizeof(float));
    if (want_normals) m->normals = malloc((nv ? nv : 1) * 3 * sizeof(float));
    if (want_uvs) m->uvs = malloc((nv ? nv : 1) * 2 * sizeof(float));
    if (m->positions == NULL || (want_normals && m->normals == NULL) || (want_uvs && m->uvs == NULL))
        return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);

    /* Reserve triangles for the common case of one per face, as far as the file can hold. */
    const ply_elem *faces = ply_find_elem(r, "face");
    if (faces != NULL && faces->count > 0) {
        uint64_t cap = faces->count;
        uint64_t per_face = r->format == PLY_ASCII ? 8 : 13;
        uint64_t fit = ply_remaining(r) / per_face + 1;
        if (cap > fit) cap = fit;
        if (cap > UINT32_MAX) cap = UINT32_MAX;
        m->indices = malloc((size_t)cap * 3 * sizeof(uint32_t));
        if (m->indices == NULL) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
        r->tri_cap = (size_t)cap;
    }

    for (size_t i = 0; i < r->elem_count; i++)
        if ((st = ply_read_element(r, &r->elems[i])) != PN_OK) return st;

    ply_finish_normals(r);
    if (m->indices == NULL)
        m->indices = malloc(sizeof(uint32_t));
    else if (r->tri_cap > m->triangle_count && m->triangle_count > 0) {
        uint32_t *shrunk = realloc(m->indices, (size_t)m->triangle_count * 3 * sizeof(uint32_t));
        if (shrunk != NULL) m->indices = shrunk;
    }
    if (m->indices == NULL) return pn_err_set(r->err, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", r->path);
    return PN_OK;
}

pn_status pn_ply_read(const char *path, pn_ply_mesh *mesh, pn_err *err) {
    if (mesh == NULL) return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "PLY reader: no mesh to fill");
    memset(mesh, 0, sizeof *mesh);
    if (path == NULL) return pn_err_set(err, PN_ERROR_INVALID_ARGUMENT, "PLY reader: no path given");

    pn_err local;
    pn_err_init(&local);
    ply_reader r;
    memset(&r, 0, sizeof r);
    r.path = path;
    r.err = &local;

    /* Only a regular file within the input limit (no device, FIFO or folder). */
    pn_err why;
    pn_err_init(&why);
    r.fp = pn_file_open_regular(path, PN_INPUT_FILE_MAX_BYTES, &r.file_size, &why);
    if (r.fp == NULL) return pn_err_set(err, why.status, "%s: %s", path, why.message);
    pn_status st;
    /* Small files get a buffer their size: fresh pages cost more than the copying. */
    r.cap = PLY_BUFFER_SIZE;
    if (r.file_size + 1 < r.cap) r.cap = (size_t)r.file_size + 1;
    if (r.cap < 2 * PLY_MAX_LINE) r.cap = 2 * PLY_MAX_LINE;
    r.buf = malloc(r.cap);
    if (r.buf == NULL)
        st = pn_err_set(&local, PN_ERROR_OUT_OF_MEMORY, "%s: out of memory", path);
    else
        st = ply_read_all(&r);
    fclose(r.fp);
    free(r.buf);
    free(r.face);
    for (size_t i = 0; i < r.elem_count; i++) free(r.elems[i].props);
    free(r.elems);

    if (st != PN_OK || local.status != PN_OK) {
        if (local.status == PN_OK) pn_err_set(&local, st, "%s: failed to read PLY file", path);
        pn_err_set(err, local.status, "%s", local.message);
        pn_ply_mesh_free(&r.mesh);
        return local.status;
    }
    *mesh = r.mesh;
    return PN_OK;
}

void pn_ply_mesh_free(pn_ply_mesh *mesh) {
    if (mesh == NULL) return;
    free(mesh->positions);
    free(mesh->normals);
    free(mesh->uvs);
    free(mesh->indices);
    memset(mesh, 0, sizeof *mesh);
}
