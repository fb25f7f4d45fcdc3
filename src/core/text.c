/* text.c — pn_text_escape (text.h): one-line, printable messages from untrusted bytes. */
#include "core/text.h"

#include <stdio.h>

/* Length (2..4) of the well-formed UTF-8 sequence of a printable character at s, or 0
 * (RFC 3629's table: no overlong forms, no surrogates, nothing above U+10FFFF; the C1 controls
 * U+0080..U+009F are refused too). */
static size_t pn_utf8_length(const unsigned char *s) {
    unsigned char c = s[0];
    size_t n;
    unsigned char lo = 0x80, hi = 0xBF; /* range of the second byte */
    if (c >= 0xC2 && c <= 0xDF) {
        n = 2;
        if (c == 0xC2) lo = 0xA0; /* U+0080..U+009F are C1 controls */
    } else if (c >= 0xE0 && c <= 0xEF) {
        n = 3;
        if (c == 0xE0) lo = 0xA0;
        if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
        n = 4;
        if (c == 0xF0) lo = 0x90;
        if (c == 0xF4) hi = 0x8F;
    } else {
        return 0;
    }
    if (s[1] < lo || s[1] > hi) return 0;
    for (size_t i = 2; i < n; i++)
        if (s[i] < 0x80 || s[i] > 0xBF) return 0;
    return n;
}

char *pn_text_escape(char *dst, size_t dst_size, const char *src) {
    const unsigned char *s = (const unsigned char *)src;
    size_t w = 0;
    while (*s) {
        size_t n = *s >= 0x20 && *s < 0x7F ? 1 : pn_utf8_length(s);
        if (n > 0) {
            if (w + n >= dst_size) break;
            for (size_t i = 0; i < n; i++) dst[w++] = (char)s[i];
            s += n;
        } else {
            if (w + 4 >= dst_size) break;
            snprintf(dst + w, 5, "\\x%02x", *s);
            w += 4;
            s++;
        }
    }
    dst[w] = '\0';
    return dst;
}
