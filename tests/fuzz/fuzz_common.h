/* fuzz_common.h — what penumbra's fuzz targets share: the bytes of one input written to a file
 * in a private folder (every reader takes a path or an open file, and the scene loader resolves
 * Includes, meshes and textures beside it), and a context that logs nothing.
 *
 * Each target defines LLVMFuzzerTestOneInput. Built with -DPN_FUZZ=ON (clang,
 * -fsanitize=fuzzer,address,undefined) it is a libFuzzer binary; in the normal build it is
 * linked with replay_main.c, which feeds it every file of its corpus folder, so that CTest runs
 * the committed corpus (seeds and regression inputs) through the real readers. */
#ifndef PN_FUZZ_COMMON_H
#define PN_FUZZ_COMMON_H

#include "penumbra/penumbra.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Writes the input to `name` in the target's private folder (made on first use, removed at
 * exit) and returns its path, or NULL when it cannot be written. */
const char *pn_fuzz_write_input(const char *name, const uint8_t *data, size_t size);

/* A context with no log callback, made once. */
pn_context pn_fuzz_context(void);

#endif
