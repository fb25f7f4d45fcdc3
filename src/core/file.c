/* file.c — opening input files: regular files within a size limit, without blocking (file.h). */
#include "core/file.h"

#include <errno.h>
#include <fcntl.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

const char *pn_file_type_name(unsigned mode) {
    if (S_ISREG(mode)) return "a regular file";
    if (S_ISDIR(mode)) return "a folder";
    if (S_ISLNK(mode)) return "a symbolic link";
    if (S_ISCHR(mode)) return "a character device";
    if (S_ISBLK(mode)) return "a block device";
    if (S_ISFIFO(mode)) return "a FIFO";
    if (S_ISSOCK(mode)) return "a socket";
    return "a special file";
}

FILE *pn_file_open_regular(const char *path, uint64_t max_bytes, uint64_t *size, pn_err *err) {
    if (size) *size = 0;
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        pn_err_set(err, PN_ERROR_IO, "%s", strerror(errno));
        return NULL;
    }
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int e = errno;
        close(fd);
        pn_err_set(err, PN_ERROR_IO, "%s", strerror(e));
        return NULL;
    }
    if (S_ISDIR(st.st_mode)) {
        close(fd);
        pn_err_set(err, PN_ERROR_IO, "%s", strerror(EISDIR));
        return NULL;
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        pn_err_set(err, PN_ERROR_BAD_INPUT, "is %s; only regular files are read",
                   pn_file_type_name((unsigned)st.st_mode));
        return NULL;
    }
    if (st.st_size < 0 || (uint64_t)st.st_size > max_bytes) {
        close(fd);
        pn_err_set(err, PN_ERROR_BAD_INPUT, "file of %llu bytes is larger than the limit of %llu bytes",
                   (unsigned long long)st.st_size, (unsigned long long)max_bytes);
        return NULL;
    }
    int flags = fcntl(fd, F_GETFL);
    FILE *file = NULL;
    if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0 || !(file = fdopen(fd, "rb"))) {
        int e = errno;
        close(fd);
        pn_err_set(err, PN_ERROR_IO, "%s", strerror(e));
        return NULL;
    }
    if (size) *size = (uint64_t)st.st_size;
    return file;
}
