/* test_ply.c — PLY reader: ascii and both binary byte orders, every scalar type, skipped
 * properties and elements, polygon triangulation, and rejection of broken or hostile files
 * (truncation, bad indices, forged counts, garbage) with a message and no crash. */
#include "harness.h"

#include "scene/ply.h"

#include <dirent.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- helpers: a scratch folder and a byte builder ------------------------------------ */

static char scratch_dir[256];

static const char *scratch_path(const char *name) {
    static char path[512];
    if (scratch_dir[0] == '\0') {
        snprintf(scratch_dir, sizeof scratch_dir, "/tmp/pn_test_ply_XXXXXX");
        if (mkdtemp(scratch_dir) == NULL) {
            snprintf(scratch_dir, sizeof scratch_dir, "/tmp");
        }
    }
    snprintf(path, sizeof path, "%s/%s", scratch_dir, name);
    return path;
}

typedef struct bytes {
    unsigned char data[8192];
    size_t len;
    int big_endian;
} bytes;

static void put_raw(bytes *b, const void *p, size_t n) {
    if (b->len + n > sizeof b->data) abort();
    const unsigned char *s = p;
    for (size_t i = 0; i < n; i++) b->data[b->len + i] = b->big_endian ? s[n - 1 - i] : s[i];
    b->len += n;
}
static void put_text(bytes *b, const char *s) {
    size_t n = strlen(s);
    if (b->len + n > sizeof b->data) abort();
    memcpy(b->data + b->len, s, n);
    b->len += n;
}
static void put_u8(bytes *b, uint8_t v) {
    put_raw(b, &v, 1);
}
static void put_i8(bytes *b, int8_t v) {
    put_raw(b, &v, 1);
}
static void put_i16(bytes *b, int16_t v) {
    put_raw(b, &v, 2);
}
static void put_u16(bytes *b, uint16_t v) {
    put_raw(b, &v, 2);
}
static void put_i32(bytes *b, int32_t v) {
    put_raw(b, &v, 4);
}
static void put_u32(bytes *b, uint32_t v) {
    put_raw(b, &v, 4);
}
static void put_f32(bytes *b, float v) {
    put_raw(b, &v, 4);
}
static void put_f64(bytes *b, double v) {
    put_raw(b, &v, 8);
}

static const char *write_file(const char *name, const void *data, size_t len) {
    const char *path = scratch_path(name);
    FILE *f = fopen(path, "wb");
    if (f == NULL) return path;
    fwrite(data, 1, len, f);
    fclose(f);
    return path;
}

static const char *write_text(const char *name, const char *text) {
    return write_file(name, text, strlen(text));
}

/* Reads path expecting failure with status and a message containing needle (and the path). */
static void expect_failure(const char *path, pn_status status, const char *needle) {
    pn_ply_mesh m;
    pn_err err;
    pn_err_init(&err);
    pn_status st = pn_ply_read(path, &m, &err);
    CHECK_MSG(st == status, "%s: status %d, expected %d (%s)", path, (int)st, (int)status, err.message);
    CHECK(err.status == status);
    CHECK_STR_CONTAINS(err.message, path);
    if (needle != NULL) CHECK_STR_CONTAINS(err.message, needle);
    CHECK(m.positions == NULL && m.indices == NULL && m.normals == NULL && m.uvs == NULL);
    pn_ply_mesh_free(&m);
}

static pn_status read_ok(const char *path, pn_ply_mesh *m) {
    pn_err err;
    pn_err_init(&err);
    pn_status st = pn_ply_read(path, m, &err);
    CHECK_MSG(st == PN_OK, "%s: %s", path, err.message);
    return st;
}

static void check_tri(const pn_ply_mesh *m, uint32_t t, uint32_t a, uint32_t b, uint32_t c) {
    CHECK(t < m->triangle_count);
    if (t >= m->triangle_count) return;
    CHECK_MSG(m->indices[3 * t] == a && m->indices[3 * t + 1] == b && m->indices[3 * t + 2] == c,
              "triangle %u is (%u %u %u), expected (%u %u %u)", t, m->indices[3 * t], m->indices[3 * t + 1],
              m->indices[3 * t + 2], a, b, c);
}

/* ---- well-formed files --------------------------------------------------------------- */

static void test_ascii_quad_normals_uvs(void) {
    const char *path = write_text("ascii.ply", "ply\n"
                                               "format ascii 1.0\n"
                                               "comment a unit square made of one quad\n"
                                               "element vertex 4\n"
                                               "property float x\nproperty float y\nproperty float z\n"
                                               "property float nx\nproperty float ny\nproperty float nz\n"
                                               "property float u\nproperty float v\n"
                                               "element face 1\n"
                                               "property list uchar int vertex_indices\n"
                                               "end_header\n"
                                               "0 0 0  0 0 2  0 0\n"
                                               "1 0 0  0 0 1  1 0\n"
                                               "1 1 0  0 3 4  1 1\n"
                                               "0 1 -1.5e1  0 0 0.5  0 1\n"
                                               "4 0 1 2 3\n");
    pn_ply_mesh m;
    if (read_ok(path, &m) != PN_OK) return;
    CHECK(m.vertex_count == 4);
    CHECK(m.triangle_count == 2);
    CHECK(m.skipped_face_count == 0);
    CHECK(m.normals != NULL && m.uvs != NULL);
    CHECK(m.positions[3] == 1.0f && m.positions[7] == 1.0f && m.positions[11] == -15.0f);
    if (m.normals) {
        CHECK_NEAR(m.normals[2], 1.0, 1e-7);
        CHECK_NEAR(m.normals[7], 0.6, 1e-7);
        CHECK_NEAR(m.normals[8], 0.8, 1e-7);
        CHECK_NEAR(m.normals[11], 1.0, 1e-7);
    }
    if (m.uvs) CHECK(m.uvs[2] == 1.0f && m.uvs[3] == 0.0f && m.uvs[7] == 1.0f);
    check_tri(&m, 0, 0, 1, 2);
    check_tri(&m, 1, 0, 2, 3);
    pn_ply_mesh_free(&m);
    CHECK(m.positions == NULL && m.vertex_count == 0);
}

static void test_ascii_crlf_polygons(void) {
    /* CRLF line ends, s/t texture names, a pentagon, a two-vertex face, values split oddly
     * across lines (records are a token stream), and no normals. */
    const char *path = write_text("crlf.ply", "ply\r\nformat ascii 1.0\r\n"
                                              "element vertex 5\r\n"
                                              "property double x\r\nproperty double y\r\nproperty double z\r\n"
                                              "property float s\r\nproperty float t\r\n"
                                              "element face 3\r\n"
                                              "property list int uint vertex_index\r\n"
                                              "end_header\r\n"
                                              "0 0 0 0 0\r\n1 0 0 1 0\r\n2 1 0 1 1\r\n1 2 0 0.5 1\r\n"
                                              "0 1 0\r\n0.25 0.75\r\n"
                                              "5 0 1 2 3 4\r\n2 0 1\r\n3 4 3 2\r\n");
    pn_ply_mesh m;
    if (read_ok(path, &m) != PN_OK) return;
    CHECK(m.vertex_count == 5);
    CHECK(m.normals == NULL);
    CHECK(m.uvs != NULL);
    CHECK(m.triangle_count == 4);
    CHECK(m.skipped_face_count == 1);
    check_tri(&m, 0, 0, 1, 2);
    check_tri(&m, 1, 0, 2, 3);
    check_tri(&m, 2, 0, 3, 4);
    check_tri(&m, 3, 4, 3, 2);
    if (m.uvs) CHECK(m.uvs[8] == 0.25f && m.uvs[9] == 0.75f);
    pn_ply_mesh_free(&m);
}

/* A binary file with double positions, a skipped scalar and a skipped list inside the vertex
 * element, an unknown element (scalars and a list) between vertices and faces, and a face
 * property after the index list. */
static size_t build_extras(bytes *b, int big_endian) {
    b->len = 0;
    b->big_endian = big_endian;
    put_text(b, "ply\n");
    put_text(b, big_endian ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n");
    put_text(b, "comment extras\n"
                "element vertex 4\n"
                "property double x\n"
                "property uchar red\n"
                "property double y\n"
                "property list ushort float weights\n"
                "property double z\n"
                "property float texture_u\n"
                "property float texture_v\n"
                "element edge 2\n"
                "property int vertex1\n"
                "property list uchar short path\n"
                "property int vertex2\n"
                "element face 2\n"
                "property list uchar int vertex_indices\n"
                "property int face_indices\n"
                "end_header\n");
    size_t header = b->len;
    for (int i = 0; i < 4; i++) {
        put_f64(b, 0.1 * i);
        put_u8(b, (uint8_t)(200 + i));
        put_f64(b, -1.0 - i);
        put_u16(b, (uint16_t)i); /* i weights */
        for (int k = 0; k < i; k++) put_f32(b, 9.0f);
        put_f64(b, 1e10);
        put_f32(b, 0.5f * (float)i);
        put_f32(b, 1.0f - 0.25f * (float)i);
    }
    for (int i = 0; i < 2; i++) {
        put_i32(b, i);
        put_u8(b, 3);
        put_i16(b, 1);
        put_i16(b, 2);
        put_i16(b, 3);
        put_i32(b, i + 1);
    }
    put_u8(b, 3);
    put_i32(b, 3);
    put_i32(b, 2);
    put_i32(b, 1);
    put_i32(b, 7);
    put_u8(b, 3);
    put_i32(b, 0);
    put_i32(b, 1);
    put_i32(b, 3);
    put_i32(b, 8);
    return header;
}

static void check_extras(const pn_ply_mesh *m) {
    CHECK(m->vertex_count == 4);
    CHECK(m->triangle_count == 2);
    CHECK(m->normals == NULL);
    CHECK(m->uvs != NULL);
    for (uint32_t i = 0; i < 4 && i < m->vertex_count; i++) {
        CHECK(m->positions[3 * i] == (float)(0.1 * i));
        CHECK(m->positions[3 * i + 1] == (float)(-1.0 - i));
        CHECK(m->positions[3 * i + 2] == 1e10f);
        if (m->uvs) {
            CHECK(m->uvs[2 * i] == 0.5f * (float)i);
            CHECK(m->uvs[2 * i + 1] == 1.0f - 0.25f * (float)i);
        }
    }
    check_tri(m, 0, 3, 2, 1);
    check_tri(m, 1, 0, 1, 3);
}

static void test_binary_little_endian_extras(void) {
    bytes b;
    build_extras(&b, 0);
    pn_ply_mesh m;
    if (read_ok(write_file("le.ply", b.data, b.len), &m) != PN_OK) return;
    check_extras(&m);
    pn_ply_mesh_free(&m);
}

static void test_binary_big_endian_extras(void) {
    bytes b;
    build_extras(&b, 1);
    pn_ply_mesh m;
    if (read_ok(write_file("be.ply", b.data, b.len), &m) != PN_OK) return;
    check_extras(&m);
    pn_ply_mesh_free(&m);
}

/* Every scalar type as a position, normal or index type, in both byte orders. */
static void test_all_scalar_types(void) {
    for (int be = 0; be < 2; be++) {
        bytes b = {.len = 0, .big_endian = be};
        put_text(&b, be ? "ply\nformat binary_big_endian 1.0\n" : "ply\nformat binary_little_endian 1.0\n");
        put_text(&b, "element vertex 3\n"
                     "property char x\nproperty int16 y\nproperty ushort z\n"
                     "property uint8 nx\nproperty int ny\nproperty uint32 nz\n"
                     "property float64 u\nproperty float32 v\n"
                     "element face 2\n"
                     "property list short ushort vertex_indices\n"
                     "property list uint32 char other\n"
                     "end_header\n");
        int8_t xs[3] = {-128, 0, 127};
        int16_t ys[3] = {-32768, 1, 32767};
        uint16_t zs[3] = {0, 2, 65535};
        for (int i = 0; i < 3; i++) {
            put_i8(&b, xs[i]);
            put_i16(&b, ys[i]);
            put_u16(&b, zs[i]);
            put_u8(&b, i == 0 ? 255 : 0);
            put_i32(&b, i == 1 ? -7 : 0);
            put_u32(&b, i == 2 ? 4000000000u : 0);
            put_f64(&b, 0.125 * i);
            put_f32(&b, 2.5f);
        }
        put_i16(&b, 3);
        put_u16(&b, 0);
        put_u16(&b, 1);
        put_u16(&b, 2);
        put_u32(&b, 2);
        put_i8(&b, -1);
        put_i8(&b, -2);
        put_i16(&b, 0);
        put_u32(&b, 0);
        pn_ply_mesh m;
        if (read_ok(write_file(be ? "types_be.ply" : "types_le.ply", b.data, b.len), &m) != PN_OK) continue;
        CHECK(m.vertex_count == 3 && m.triangle_count == 1 && m.skipped_face_count == 1);
        for (int i = 0; i < 3 && m.vertex_count == 3; i++) {
            CHECK(m.positions[3 * i] == (float)xs[i]);
            CHECK(m.positions[3 * i + 1] == (float)ys[i]);
            CHECK(m.positions[3 * i + 2] == (float)zs[i]);
            CHECK(m.uvs != NULL && m.uvs[2 * i] == 0.125f * (float)i && m.uvs[2 * i + 1] == 2.5f);
        }
        CHECK(m.normals != NULL);
        if (m.normals) {
            CHECK(m.normals[0] == 1.0f && m.normals[1] == 0.0f);
            CHECK(m.normals[4] == -1.0f && m.normals[8] == 1.0f);
        }
        check_tri(&m, 0, 0, 1, 2);
        pn_ply_mesh_free(&m);
    }
}

static void test_vertices_after_faces_and_no_faces(void) {
    const char *path =
        write_text("order.ply", "ply\nformat ascii 1.0\n"
                                "element face 1\nproperty list uchar uint vertex_indices\n"
                                "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                "end_header\n3 2 1 0\n0 0 0\n1 0 0\n0 1 0\n");
    pn_ply_mesh m;
    if (read_ok(path, &m) == PN_OK) {
        CHECK(m.vertex_count == 3 && m.triangle_count == 1);
        check_tri(&m, 0, 2, 1, 0);
        CHECK(m.positions[7] == 1.0f);
        pn_ply_mesh_free(&m);
    }
    path = write_text("points.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                    "property float x\nproperty float y\nproperty float z\n"
                                    "end_header\n1 2 3\n");
    if (read_ok(path, &m) == PN_OK) {
        CHECK(m.vertex_count == 1 && m.triangle_count == 0 && m.indices != NULL);
        pn_ply_mesh_free(&m);
    }
}

static void test_zero_normal_drops_normals(void) {
    const char *path = write_text("zeronormal.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                                    "property float x\nproperty float y\nproperty float z\n"
                                                    "property float nx\nproperty float ny\nproperty float nz\n"
                                                    "element face 1\nproperty list uchar int vertex_indices\n"
                                                    "end_header\n0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n3 0 1 2\n");
    pn_ply_mesh m;
    if (read_ok(path, &m) != PN_OK) return;
    CHECK(m.normals == NULL);
    CHECK(m.triangle_count == 1);
    pn_ply_mesh_free(&m);
}

/* ---- broken and hostile files -------------------------------------------------------- */

static void test_truncated_binary(void) {
    bytes b;
    size_t header = build_extras(&b, 0);
    /* Every cut inside the header and the body must fail cleanly. */
    for (size_t len = 0; len < b.len; len++) {
        char name[64];
        snprintf(name, sizeof name, "cut_%zu.ply", len);
        const char *path = write_file(name, b.data, len);
        expect_failure(path, PN_ERROR_BAD_INPUT, NULL);
        unlink(path);
    }
    /* Plain vertices (fixed-size records): the message says how far the file got. */
    bytes v = {.len = 0, .big_endian = 0};
    put_text(&v, "ply\nformat binary_little_endian 1.0\nelement vertex 40\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n");
    for (int i = 0; i < 12; i++) {
        put_f32(&v, 1.0f);
        put_f32(&v, 2.0f);
        put_f32(&v, 3.0f);
    }
    expect_failure(write_file("cut_vertices.ply", v.data, v.len), PN_ERROR_BAD_INPUT,
                   "file ends after 12 of 40 vertices");
    (void)header;
}

static void test_truncated_faces_message(void) {
    bytes b = {.len = 0, .big_endian = 0};
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element face 3\nproperty list uchar int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; i++) put_f32(&b, (float)i);
    put_u8(&b, 3);
    put_i32(&b, 0);
    put_i32(&b, 1);
    put_i32(&b, 2);
    put_u8(&b, 4); /* claims four items, then the file stops after two */
    put_i32(&b, 0);
    put_i32(&b, 1);
    put_u8(&b, 3);
    expect_failure(write_file("cut_faces.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "file ends after 1 of 3 faces");
}

static void test_truncated_ascii(void) {
    const char *path = write_text("cut_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                                   "property float x\nproperty float y\nproperty float z\n"
                                                   "element face 2\nproperty list uchar int vertex_indices\n"
                                                   "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1\n");
    expect_failure(path, PN_ERROR_BAD_INPUT, "file ends after 1 of 2 faces");
    path = write_text("bad_number.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                        "property float x\nproperty float y\nproperty float z\n"
                                        "end_header\n0 zero 0\n");
    expect_failure(path, PN_ERROR_BAD_INPUT, "line 8: 'zero' is not a number");
    path = write_text("huge_ascii_list.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                             "property float x\nproperty float y\nproperty float z\n"
                                             "element face 1\nproperty list uint int vertex_indices\n"
                                             "end_header\n0 0 0\n4000000000 0 0 0\n");
    expect_failure(path, PN_ERROR_BAD_INPUT, "file ends after 0 of 1 faces");
}

static void test_index_out_of_range(void) {
    const char *path = write_text("badindex.ply", "ply\nformat ascii 1.0\nelement vertex 4\n"
                                                  "property float x\nproperty float y\nproperty float z\n"
                                                  "element face 2\nproperty list uchar int vertex_indices\n"
                                                  "end_header\n0 0 0\n1 0 0\n0 1 0\n1 1 0\n3 0 1 2\n3 0 7 2\n");
    expect_failure(path, PN_ERROR_BAD_INPUT, "face 1 refers to vertex 7 but there are 4 vertices");

    bytes b = {.len = 0, .big_endian = 0};
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; i++) put_f32(&b, (float)i);
    put_u8(&b, 3);
    put_i32(&b, 0);
    put_i32(&b, -1);
    put_i32(&b, 2);
    expect_failure(write_file("negindex.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "face 0 refers to vertex -1");
}

static void test_missing_file(void) {
    expect_failure(scratch_path("does_not_exist.ply"), PN_ERROR_IO, "No such file");
    expect_failure(scratch_dir, PN_ERROR_IO, NULL);
}

static void test_garbage_and_bad_headers(void) {
    expect_failure(write_text("garbage.ply", "this is not a mesh at all\n"), PN_ERROR_BAD_INPUT, "not a PLY file");
    expect_failure(write_text("empty.ply", ""), PN_ERROR_BAD_INPUT, "not a PLY file");
    unsigned char gz[] = {0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 0, 3};
    expect_failure(write_file("mesh.ply.gz", gz, sizeof gz), PN_ERROR_BAD_INPUT, "gzip");
    unsigned char noise[600];
    for (size_t i = 0; i < sizeof noise; i++) noise[i] = (unsigned char)(i * 131u + 7u);
    expect_failure(write_file("noise.ply", noise, sizeof noise), PN_ERROR_BAD_INPUT, "not a PLY file");

    expect_failure(write_text("badtype.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                             "property float x\nproperty foo y\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "header: unknown property type 'foo' on line 5");
    expect_failure(write_text("noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                           "property float x\n"),
                   PN_ERROR_BAD_INPUT, "end_header");
    expect_failure(write_text("noformat.ply", "ply\nelement vertex 0\nproperty float x\n"
                                              "property float y\nproperty float z\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "format");
    expect_failure(write_text("badformat.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "unknown format");
    expect_failure(write_text("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                           "property float x\nproperty float y\nend_header\n0 0\n"),
                   PN_ERROR_BAD_INPUT, "x, y, z");
    expect_failure(write_text("novertex.ply", "ply\nformat ascii 1.0\nend_header\n"), PN_ERROR_BAD_INPUT,
                   "no vertex element");
    expect_failure(write_text("floatcount.ply", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                                                "property float y\nproperty float z\nelement face 0\n"
                                                "property list float int vertex_indices\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "not an integer type");
    expect_failure(write_text("badcount.ply", "ply\nformat ascii 1.0\nelement vertex -3\n"
                                              "end_header\n"),
                   PN_ERROR_BAD_INPUT, "bad element count");
    char longline[6000];
    memset(longline, 'a', sizeof longline);
    memcpy(longline, "ply\ncomment ", 12);
    longline[sizeof longline - 1] = '\0';
    expect_failure(write_text("longline.ply", longline), PN_ERROR_BAD_INPUT, "too long");
}

static void test_forged_counts(void) {
    /* 2^31 vertices claimed by a file of a few hundred bytes. */
    expect_failure(write_text("huge_vertices.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 2147483648\n"
                                                   "property float x\nproperty float y\nproperty float z\n"
                                                   "end_header\n\1\2\3\4\5\6\7\10\11\12\13\14"),
                   PN_ERROR_BAD_INPUT, "2147483648");
    expect_failure(write_text("huge_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 2147483648\n"
                                                "property float x\nproperty float y\nproperty float z\n"
                                                "end_header\n0 0 0\n"),
                   PN_ERROR_BAD_INPUT, "2147483648");
    expect_failure(write_text("too_many_vertices.ply",
                              "ply\nformat binary_little_endian 1.0\nelement vertex 4294967296\n"
                              "property float x\nproperty float y\nproperty float z\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "vertices");
    expect_failure(write_text("huge_other.ply", "ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
                                                "property float x\nproperty float y\nproperty float z\n"
                                                "element junk 18446744073709551615\nproperty uchar a\nend_header\n"),
                   PN_ERROR_BAD_INPUT, "junk");
    expect_failure(write_text("overflow_count.ply", "ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n"
                                                    "end_header\n"),
                   PN_ERROR_BAD_INPUT, "bad element count");

    /* A face list whose length says four billion items. */
    bytes b = {.len = 0, .big_endian = 0};
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list uint int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; i++) put_f32(&b, (float)i);
    put_u32(&b, 0xFFFFFFFFu);
    put_i32(&b, 0);
    expect_failure(write_file("huge_list.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "file ends after 0 of 1 faces");

    /* The same through a skipped list of an unknown element. */
    b.len = 0;
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 0\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element junk 1\nproperty list uint double stuff\nend_header\n");
    put_u32(&b, 0xFFFFFFFFu);
    expect_failure(write_file("huge_skip.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "file ends after 0 of 1 junks");

    /* Negative list lengths, binary and ascii. */
    b.len = 0;
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 3\n"
                 "property float x\nproperty float y\nproperty float z\n"
                 "element face 1\nproperty list int int vertex_indices\nend_header\n");
    for (int i = 0; i < 9; i++) put_f32(&b, (float)i);
    put_i32(&b, -3);
    put_i32(&b, 0);
    put_i32(&b, 1);
    put_i32(&b, 2);
    expect_failure(write_file("neg_list.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "negative");
    expect_failure(write_text("neg_list_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 1\n"
                                                    "property float x\nproperty float y\nproperty float z\n"
                                                    "element face 1\nproperty list char int vertex_indices\n"
                                                    "end_header\n0 0 0\n-1 0\n"),
                   PN_ERROR_BAD_INPUT, "negative");
}

static void test_non_finite_values(void) {
    expect_failure(write_text("nan_ascii.ply", "ply\nformat ascii 1.0\nelement vertex 2\n"
                                               "property float x\nproperty float y\nproperty float z\n"
                                               "end_header\n0 0 0\n0 nan 0\n"),
                   PN_ERROR_BAD_INPUT, "vertex 1");
    bytes b = {.len = 0, .big_endian = 0};
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
                 "property float x\nproperty float y\nproperty float z\nend_header\n");
    put_f32(&b, 0.0f);
    put_f32(&b, 0.0f);
    put_f32(&b, NAN);
    expect_failure(write_file("nan_binary.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "not a finite number");
    b.len = 0;
    put_text(&b, "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
                 "property double x\nproperty float y\nproperty float z\nend_header\n");
    put_f64(&b, 1e300); /* finite as a double, infinite as a float */
    put_f32(&b, 0.0f);
    put_f32(&b, 0.0f);
    expect_failure(write_file("inf_binary.ply", b.data, b.len), PN_ERROR_BAD_INPUT, "not a finite number");
}

static void test_first_error_wins(void) {
    pn_err err;
    pn_err_init(&err);
    pn_err_set(&err, PN_ERROR_UNSUPPORTED, "earlier problem");
    pn_ply_mesh m;
    pn_status st = pn_ply_read(scratch_path("does_not_exist.ply"), &m, &err);
    CHECK(st == PN_ERROR_IO);
    CHECK(err.status == PN_ERROR_UNSUPPORTED);
    CHECK_STR_CONTAINS(err.message, "earlier problem");
}

/* Flips and overwrites bytes of a valid file at pseudo-random places: the reader must either
 * succeed with in-range indices or fail with BAD_INPUT, never crash (run under ASan in CI). */
static void test_mutated_files(void) {
    bytes b;
    build_extras(&b, 0);
    uint32_t state = 12345u;
    for (int round = 0; round < 400; round++) {
        bytes m = b;
        int edits = 1 + round % 4;
        for (int k = 0; k < edits; k++) {
            state = state * 1664525u + 1013904223u;
            size_t at = (state >> 8) % m.len;
            state = state * 1664525u + 1013904223u;
            m.data[at] = (unsigned char)(state >> 24);
        }
        const char *path = write_file("mutated.ply", m.data, m.len);
        pn_ply_mesh mesh;
        pn_err err;
        pn_err_init(&err);
        pn_status st = pn_ply_read(path, &mesh, &err);
        CHECK_MSG(st == PN_OK || st == PN_ERROR_BAD_INPUT, "round %d: %s", round, err.message);
        if (st == PN_OK) {
            int bad = 0;
            for (size_t i = 0; i < 3 * (size_t)mesh.triangle_count; i++) bad += mesh.indices[i] >= mesh.vertex_count;
            CHECK(bad == 0);
        } else {
            CHECK_STR_CONTAINS(err.message, path);
        }
        pn_ply_mesh_free(&mesh);
    }
}

/* ---- a real scene mesh ---------------------------------------------------------------- */

/* Finds the first .ply file under dir (depth-first); returns 1 and fills out if found. */
static int find_ply(const char *dir, char *out, size_t size, int depth) {
    if (depth > 4) return 0;
    DIR *d = opendir(dir);
    if (d == NULL) return 0;
    struct dirent *ent;
    int found = 0;
    while (!found && (ent = readdir(d)) != NULL) {
        if (ent->d_name[0] == '.') continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir, ent->d_name);
        size_t n = strlen(ent->d_name);
        struct stat sb;
        if (stat(path, &sb) != 0) continue;
        if (S_ISDIR(sb.st_mode)) {
            found = find_ply(path, out, size, depth + 1);
        } else if (n > 4 && strcmp(ent->d_name + n - 4, ".ply") == 0) {
            snprintf(out, size, "%s", path);
            found = 1;
        }
    }
    closedir(d);
    return found;
}

static void test_real_scene_mesh(void) {
    char dir[1024], path[1024];
    snprintf(dir, sizeof dir, "%s/scenes/veach-ajar/models", PN_SHARED_DIR);
    if (!find_ply(dir, path, sizeof path, 0)) {
        snprintf(dir, sizeof dir, "%s/scenes", PN_SHARED_DIR);
        if (PN_SHARED_DIR[0] == '\0' || !find_ply(dir, path, sizeof path, 0)) {
            pn_test_skip("no scene PLY files under PN_SHARED_DIR/scenes");
            return;
        }
    }
    pn_ply_mesh m;
    if (read_ok(path, &m) != PN_OK) return;
    CHECK(m.vertex_count > 0);
    CHECK(m.triangle_count > 0);
    int bad = 0;
    for (size_t i = 0; i < 3 * (size_t)m.triangle_count; i++) bad += m.indices[i] >= m.vertex_count;
    CHECK(bad == 0);
    for (size_t i = 0; i < 3 * (size_t)m.vertex_count; i++) bad += !isfinite(m.positions[i]);
    CHECK(bad == 0);
    if (m.normals) {
        for (size_t i = 0; i < m.vertex_count; i++) {
            const float *n = m.normals + 3 * i;
            double len = sqrt((double)(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]));
            bad += fabs(len - 1.0) > 1e-5;
        }
        CHECK(bad == 0);
    }
    pn_ply_mesh_free(&m);
}

/* Removes the scratch files; runs last. */
static void test_cleanup(void) {
    if (scratch_dir[0] == '\0' || strcmp(scratch_dir, "/tmp") == 0) return;
    DIR *d = opendir(scratch_dir);
    if (d == NULL) return;
    struct dirent *ent;
    while ((ent = readdir(d)) != NULL) {
        if (ent->d_name[0] == '.') continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", scratch_dir, ent->d_name);
        unlink(path);
    }
    closedir(d);
    CHECK(rmdir(scratch_dir) == 0);
}

PN_TESTS(TEST(test_ascii_quad_normals_uvs), TEST(test_ascii_crlf_polygons), TEST(test_binary_little_endian_extras),
         TEST(test_binary_big_endian_extras), TEST(test_all_scalar_types), TEST(test_vertices_after_faces_and_no_faces),
         TEST(test_zero_normal_drops_normals), TEST(test_truncated_binary), TEST(test_truncated_faces_message),
         TEST(test_truncated_ascii), TEST(test_index_out_of_range), TEST(test_missing_file),
         TEST(test_garbage_and_bad_headers), TEST(test_forged_counts), TEST(test_non_finite_values),
         TEST(test_first_error_wins), TEST(test_mutated_files), TEST(test_real_scene_mesh), TEST(test_cleanup))
