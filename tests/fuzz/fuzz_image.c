/* fuzz_image.c — fuzz targets of the image readers, one binary per reader: compiled with
 * PN_FUZZ_READER = 1 EXR (OpenEXR core), 2 PNG (libpng), 3 JPEG (libjpeg-turbo), 4 the stb_image
 * formats (TGA, BMP, HDR, PSD), 5 PFM; the EXR target also reads every layer (pn_exr_read_layers,
 * `penumbra merge`'s reader). The reader is called directly, not through the sniffing
 * of pn_image_read_file, so that each target's corpus reaches its own reader; the pixel limit is
 * lowered to 2^22 so that large but valid headers do not spend the fuzzer's time. */
#include "fuzz_common.h"

#include "io/image.h"

#include <sys/stat.h>

#ifndef PN_FUZZ_READER
#error "PN_FUZZ_READER selects the reader (see tests/fuzz/CMakeLists.txt)"
#endif

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    const char *path = pn_fuzz_write_input("image", data, size);
    if (!path) return 0;
    FILE *file = fopen(path, "rb");
    if (!file) return 0;
    pn_image_limits limits = {(uint64_t)size, (uint64_t)1 << 22};
    pn_image image = NULL;
    pn_err err;
    pn_err_init(&err);
#if PN_FUZZ_READER == 1
    pn_exr_read(file, "image.exr", &limits, &image, &err);
    /* And every layer with its windows, as `penumbra merge` reads its parts. */
    pn_image_free(image);
    image = NULL;
    rewind(file);
    pn_err_init(&err);
    pn_exr_read_layers(file, "image.exr", &limits, &image, &err);
#elif PN_FUZZ_READER == 2
    pn_png_read(file, "image.png", 0.0f, &limits, &image, &err);
#elif PN_FUZZ_READER == 3
    pn_jpeg_read(file, "image.jpg", 0.0f, &limits, &image, &err);
#elif PN_FUZZ_READER == 4
    pn_ldr_read(file, "image", 0.0f, &limits, &image, &err);
#else
    pn_pfm_read(file, "image.pfm", &limits, &image, &err);
#endif
    fclose(file);
    pn_image_free(image);
    return 0;
}
