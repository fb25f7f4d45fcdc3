/* file.h — opening input files safely: only regular files, within a size limit, never blocking.
 *
 * Every file penumbra reads (scene files and their Includes, PLY meshes, textures and images)
 * is opened here, so that a device (/dev/zero), a FIFO or a folder named as input gives a
 * message instead of unbounded memory growth or a hang. */
#ifndef PN_CORE_FILE_H
#define PN_CORE_FILE_H

#include "core/error.h"

#include <stdint.h>
#include <stdio.h>

/* The largest input file penumbra reads (8 GiB): well above any scene, mesh or texture of the
 * scale ARCHITECTURE.md names (10 million triangles of binary PLY are about 300 MB). */
#define PN_INPUT_FILE_MAX_BYTES ((uint64_t)1 << 33)

/* Opens `path` for reading when it is a regular file of at most `max_bytes` bytes; the open
 * uses O_NONBLOCK so that a FIFO cannot block it, and the descriptor is made blocking again
 * before it is returned. On success returns the stream and stores the file's size in *size.
 * On failure returns NULL and sets err to why, without the path (callers say which file and
 * in what role): PN_ERROR_IO when the system could not
 * open it or it is a folder (strerror), PN_ERROR_BAD_INPUT when it is another kind of file than a
 * regular one, or too large. */
FILE *pn_file_open_regular(const char *path, uint64_t max_bytes, uint64_t *size, pn_err *err);

/* "a folder", "a symbolic link", "a character device", ... for a stat st_mode, for messages. */
const char *pn_file_type_name(unsigned mode);

#endif
