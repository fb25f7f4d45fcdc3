/* settings.h — the public entry points' guard of pn_render_settings (its struct_size): the
 * caller's settings copied into this version's layout. */
#ifndef PN_DRIVER_SETTINGS_H
#define PN_DRIVER_SETTINGS_H

#include <penumbra/penumbra.h>

/* Copies the caller's settings into *out (this library's layout): the first struct_size bytes
 * (0: this layout), the rest zero. A size smaller than this layout's, or a larger one whose
 * extra bytes are not all zero (options this library does not know), is PN_ERROR_INVALID_ARGUMENT
 * with a message on ctx naming `who`. */
pn_status pn_render_settings_copy(pn_context ctx, const char *who, const pn_render_settings *in,
                                  pn_render_settings *out);

#endif
