/* consumer.c — a third-party program that sees penumbra only as an installed package.
 *
 * It is compiled twice by tests/install/run.sh: once with the flags from penumbra.pc and once
 * through find_package(penumbra). It includes nothing but the public header and calls a few
 * entry points, so a missing symbol, a wrong include path or a header/library mismatch shows up
 * as a build failure or a non-zero exit.
 *
 * Usage: consumer SCENE_PATH
 *   The scene may be absent or invalid: the load must then fail cleanly (PN_ERROR_IO or
 *   PN_ERROR_BAD_INPUT, a non-empty error message, no scene handed back). A scene that loads is
 *   accepted too, after its statistics have been read.
 */
#include <penumbra/penumbra.h>

#include <stdio.h>
#include <string.h>

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s SCENE_PATH\n", argc > 0 ? argv[0] : "consumer");
        return 2;
    }

    const char *version = pn_version_string();
    if (version == NULL) {
        fprintf(stderr, "consumer: pn_version_string() returned NULL\n");
        return 1;
    }
    printf("penumbra %s\n", version);
    /* The header and the library must come from the same release. */
    if (strcmp(version, PN_VERSION_STRING) != 0) {
        fprintf(stderr, "consumer: library reports %s but the header is %s\n", version,
                PN_VERSION_STRING);
        return 1;
    }

    pn_context ctx = pn_context_new();
    if (ctx == NULL) {
        fprintf(stderr, "consumer: pn_context_new() failed\n");
        return 1;
    }

    int result = 1;
    pn_scene scene = NULL;
    pn_status status = pn_scene_load(ctx, argv[1], &scene);
    if (status == PN_OK) {
        pn_scene_info info;
        memset(&info, 0, sizeof info);
        if (scene == NULL) {
            fprintf(stderr, "consumer: pn_scene_load succeeded without a scene\n");
        } else if (pn_scene_get_info(scene, &info) != PN_OK) {
            fprintf(stderr, "consumer: pn_scene_get_info failed: %s\n",
                    pn_context_error_message(ctx));
        } else {
            printf("loaded %s: %llu triangles\n", argv[1], (unsigned long long)info.triangles);
            result = 0;
        }
    } else if (status == PN_ERROR_IO || status == PN_ERROR_BAD_INPUT) {
        const char *message = pn_context_error_message(ctx);
        if (scene != NULL) {
            fprintf(stderr, "consumer: failed load left a scene behind\n");
        } else if (message == NULL || message[0] == '\0') {
            fprintf(stderr, "consumer: load failed (%s) without an error message\n",
                    pn_status_string(status));
        } else {
            printf("load failed as expected (%s): %s\n", pn_status_string(status), message);
            result = 0;
        }
    } else {
        fprintf(stderr, "consumer: unexpected status %d (%s) from pn_scene_load: %s\n",
                (int)status, pn_status_string(status), pn_context_error_message(ctx));
    }

    pn_scene_free(scene);
    pn_context_free(ctx);
    return result;
}
