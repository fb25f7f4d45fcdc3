/* text.h — making text from files safe to print: one line, no control bytes (issue 19). */
#ifndef PN_CORE_TEXT_H
#define PN_CORE_TEXT_H

#include <stddef.h>

/* Copies `src` into `dst` (dst_size > 0; always NUL-terminated, truncated at a whole escape)
 * keeping printable ASCII and well-formed UTF-8 of printable characters, and writing every
 * other byte as "\xNN": line breaks, tabs, ESC and the other C0 controls, DEL, C1 controls
 * (U+0080..U+009F) and bytes of malformed UTF-8. A backslash is kept as it is, so that escaping
 * already escaped text changes nothing. Every message the library records (pn_err_set), logs
 * or lists as a warning passes through it: messages quote names, strings and reasons taken
 * from files (scene strings, EXR attribute names, decoder reasons). Returns dst. */
char *pn_text_escape(char *dst, size_t dst_size, const char *src);

#endif
