/* fuzz_ply.c — fuzz target of the PLY reader (ASCII and binary, both byte orders): any bytes
 * must give a mesh or an error status. */
#include "fuzz_common.h"

#include "scene/ply.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    const char *path = pn_fuzz_write_input("mesh.ply", data, size);
    if (!path) return 0;
    pn_ply_mesh mesh;
    pn_err err;
    pn_err_init(&err);
    pn_ply_read(path, &mesh, &err);
    pn_ply_mesh_free(&mesh);
    return 0;
}
