/* fuzz_scene.c — fuzz target of the pbrt-v4 scene loader (tokenizer, parser, shapes, lights,
 * materials, Embree scene build): any bytes as a scene file must give PN_OK or an error status,
 * never a crash, leak or undefined behaviour. Dictionary: scene.dict (pbrt-v4 keywords). */
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    const char *path = pn_fuzz_write_input("scene.pbrt", data, size);
    if (!path) return 0;
    pn_scene scene = NULL;
    pn_context ctx = pn_fuzz_context();
    pn_scene_load(ctx, path, &scene);
    pn_scene_free(scene);
    pn_context_clear_error(ctx);
    return 0;
}
