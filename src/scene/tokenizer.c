/* tokenizer.c — the pbrt-v4 scene file tokenizer: strings, words, brackets, comments, locations. */
#include "scene/tokenizer.h"

#include "core/file.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

pn_status pn_loc_error(const pn_srcloc *loc, pn_status status, pn_err *err, const char *fmt, ...) {
    char msg[900];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (loc && loc->file) return pn_err_set(err, status, "%s:%d:%d: %s", loc->file, loc->line, loc->column, msg);
    return pn_err_set(err, status, "%s", msg);
}

static void tokenizer_reset(pn_tokenizer *tz, const char *path) {
    tz->pos = 0;
    tz->line = 1;
    tz->column = 1;
    tz->path = path;
    tz->has_peeked = false;
    /* A UTF-8 byte order mark is skipped; it is not part of any token. */
    if (tz->size >= 3 && (unsigned char)tz->data[0] == 0xEF && (unsigned char)tz->data[1] == 0xBB &&
        (unsigned char)tz->data[2] == 0xBF)
        tz->pos = 3;
}

static pn_status check_encoding(pn_tokenizer *tz, pn_err *err) {
    const unsigned char *c = (const unsigned char *)tz->data;
    if (tz->size >= 2 && ((c[0] == 0xFE && c[1] == 0xFF) || (c[0] == 0xFF && c[1] == 0xFE))) {
        pn_srcloc loc = {tz->path, 1, 1};
        return pn_loc_error(&loc, PN_ERROR_BAD_INPUT, err,
                            "the file is encoded in UTF-16; pbrt scene files must be ASCII or UTF-8");
    }
    return PN_OK;
}

pn_status pn_tokenizer_open(pn_tokenizer *tz, const char *path, const pn_srcloc *at, pn_err *err) {
    memset(tz, 0, sizeof *tz);
    char where[600] = "";
    if (at && at->file) snprintf(where, sizeof where, "%s:%d:%d: ", at->file, at->line, at->column);
    /* Only a regular file within the input limit: a device (/dev/zero) or a FIFO named in an
     * Include must not grow memory without bound or block. */
    pn_err why;
    pn_err_init(&why);
    uint64_t file_size = 0;
    FILE *f = pn_file_open_regular(path, PN_INPUT_FILE_MAX_BYTES, &file_size, &why);
    if (!f)
        return pn_err_set(err, PN_ERROR_BAD_INPUT, "%scannot %s scene file \"%s\": %s", where,
                          why.status == PN_ERROR_IO ? "open" : "read", path, why.message);
    /* The size is known and bounded; a file that grows while it is read is read up to the size
     * it had when opened. */
    size_t n = 0, cap = (size_t)file_size;
    char *data = malloc(cap + 1);
    if (!data) {
        fclose(f);
        return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "%sout of memory reading \"%s\"", where, path);
    }
    while (n < cap) {
        size_t got = fread(data + n, 1, cap - n, f);
        if (got == 0) break;
        n += got;
    }
    if (ferror(f)) {
        int e = errno;
        free(data);
        fclose(f);
        return pn_err_set(err, PN_ERROR_IO, "%serror reading \"%s\": %s", where, path, strerror(e));
    }
    fclose(f);
    data[n] = '\0';
    tz->data = data;
    tz->size = n;
    tokenizer_reset(tz, path);
    pn_status st2 = check_encoding(tz, err);
    if (st2 != PN_OK) pn_tokenizer_close(tz);
    return st2;
}

pn_status pn_tokenizer_open_string(pn_tokenizer *tz, const char *name, const char *text, pn_err *err) {
    memset(tz, 0, sizeof *tz);
    size_t n = strlen(text);
    tz->data = malloc(n + 1);
    if (!tz->data) return pn_err_set(err, PN_ERROR_OUT_OF_MEMORY, "out of memory");
    memcpy(tz->data, text, n + 1);
    tz->size = n;
    tokenizer_reset(tz, name);
    return check_encoding(tz, err);
}

void pn_tokenizer_close(pn_tokenizer *tz) {
    if (!tz) return;
    free(tz->data);
    tz->data = NULL;
    tz->size = tz->pos = 0;
    tz->has_peeked = false;
}

static inline void advance(pn_tokenizer *tz) {
    if (tz->data[tz->pos] == '\n') {
        tz->line++;
        tz->column = 1;
    } else {
        tz->column++;
    }
    tz->pos++;
}

static int decode_escape(char c) {
    switch (c) {
    case 'b': return '\b';
    case 'f': return '\f';
    case 'n': return '\n';
    case 'r': return '\r';
    case 't': return '\t';
    case '\\': return '\\';
    case '\'': return '\'';
    case '"': return '"';
    default: return -1;
    }
}

static inline bool is_delimiter(char c) {
    return c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '"' || c == '[' || c == ']' || c == '#' || c == '\0';
}

static pn_status scan(pn_tokenizer *tz, pn_token *tok, pn_err *err) {
    for (;;) {
        if (tz->pos >= tz->size) {
            tok->kind = PN_TOKEN_EOF;
            tok->text = "";
            tok->len = 0;
            tok->loc = (pn_srcloc){tz->path, tz->line, tz->column};
            return PN_OK;
        }
        char c = tz->data[tz->pos];
        if (c == ' ' || c == '\n' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
            advance(tz);
            continue;
        }
        if (c == '#') {
            while (tz->pos < tz->size && tz->data[tz->pos] != '\n') advance(tz);
            continue;
        }
        tok->loc = (pn_srcloc){tz->path, tz->line, tz->column};
        if (c == '\0')
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                "unexpected NUL byte (is this a binary file rather than a pbrt scene?)");
        if (c == '[' || c == ']') {
            tok->kind = c == '[' ? PN_TOKEN_LBRACKET : PN_TOKEN_RBRACKET;
            tok->text = tz->data + tz->pos;
            tok->len = 1;
            advance(tz);
            return PN_OK;
        }
        if (c == '"') {
            advance(tz);
            /* Unescaped bytes are written over the raw ones: the result is never longer. */
            char *out = tz->data + tz->pos;
            char *w = out;
            for (;;) {
                if (tz->pos >= tz->size)
                    return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                        "unterminated string (the file ends before the closing quote)");
                char d = tz->data[tz->pos];
                if (d == '"') {
                    advance(tz);
                    break;
                }
                if (d == '\n' || d == '\r')
                    return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                        "unterminated string (the line ends before the closing quote)");
                if (d == '\\') {
                    pn_srcloc esc = {tz->path, tz->line, tz->column};
                    advance(tz);
                    if (tz->pos >= tz->size)
                        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err,
                                            "unterminated string (the file ends after '\\')");
                    int e = decode_escape(tz->data[tz->pos]);
                    if (e < 0) {
                        unsigned char bad = (unsigned char)tz->data[tz->pos];
                        if (bad >= 32 && bad < 127)
                            return pn_loc_error(&esc, PN_ERROR_BAD_INPUT, err,
                                                "unknown escape sequence \"\\%c\" in string", bad);
                        return pn_loc_error(&esc, PN_ERROR_BAD_INPUT, err,
                                            "unknown escape sequence (byte 0x%02x) in string", bad);
                    }
                    advance(tz);
                    *w++ = (char)e;
                    continue;
                }
                advance(tz);
                *w++ = d;
            }
            *w = '\0'; /* overwrites at most the closing quote, already consumed */
            tok->kind = PN_TOKEN_STRING;
            tok->text = out;
            tok->len = (size_t)(w - out);
            return PN_OK;
        }
        /* A bare word: runs to whitespace, a quote, a bracket or a comment. */
        size_t start = tz->pos;
        while (tz->pos < tz->size && !is_delimiter(tz->data[tz->pos])) advance(tz);
        tok->kind = PN_TOKEN_WORD;
        tok->text = tz->data + start;
        tok->len = tz->pos - start;
        return PN_OK;
    }
}

pn_status pn_tokenizer_next(pn_tokenizer *tz, pn_token *tok, pn_err *err) {
    if (tz->has_peeked) {
        *tok = tz->peeked;
        tz->has_peeked = false;
        return PN_OK;
    }
    return scan(tz, tok, err);
}

pn_status pn_tokenizer_peek(pn_tokenizer *tz, pn_token *tok, pn_err *err) {
    if (!tz->has_peeked) {
        pn_status st = scan(tz, &tz->peeked, err);
        if (st != PN_OK) return st;
        tz->has_peeked = true;
    }
    *tok = tz->peeked;
    return PN_OK;
}

bool pn_token_is(const pn_token *tok, const char *s) {
    size_t n = strlen(s);
    return tok->kind == PN_TOKEN_WORD && tok->len == n && memcmp(tok->text, s, n) == 0;
}

static bool word_equals_nocase(const char *p, size_t n, const char *s) {
    size_t m = strlen(s);
    if (n != m) return false;
    for (size_t i = 0; i < n; i++) {
        char a = p[i];
        if (a >= 'A' && a <= 'Z') a = (char)(a - 'A' + 'a');
        if (a != s[i]) return false;
    }
    return true;
}

bool pn_token_is_numeric(const pn_token *tok) {
    if (tok->kind != PN_TOKEN_WORD || tok->len == 0) return false;
    char c = tok->text[0];
    if ((c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.') return true;
    return word_equals_nocase(tok->text, tok->len, "nan") || word_equals_nocase(tok->text, tok->len, "inf") ||
           word_equals_nocase(tok->text, tok->len, "infinity");
}

/* Exact powers of ten representable in a double (Clinger's fast path). */
static const double pn_pow10_exact[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                          1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* Decimal numbers with at most 15 significant digits and a small exponent are converted exactly
 * without strtod (which is slower and depends on the locale); anything else falls back to it. */
static bool parse_decimal_fast(const char *s, size_t n, double *out) {
    size_t i = 0;
    bool neg = false;
    if (i < n && (s[i] == '-' || s[i] == '+')) neg = s[i++] == '-';
    uint64_t mant = 0;
    int digits = 0, frac_digits = 0;
    bool any = false;
    while (i < n && s[i] >= '0' && s[i] <= '9') {
        any = true;
        if (mant == 0 && s[i] == '0') {
            i++;
            continue;
        }
        if (++digits > 15) return false;
        mant = mant * 10 + (uint64_t)(s[i++] - '0');
    }
    if (i < n && s[i] == '.') {
        i++;
        while (i < n && s[i] >= '0' && s[i] <= '9') {
            any = true;
            if (mant == 0 && s[i] == '0') {
                frac_digits++;
                i++;
                continue;
            }
            if (++digits > 15) return false;
            mant = mant * 10 + (uint64_t)(s[i++] - '0');
            frac_digits++;
        }
    }
    if (!any) return false;
    int exp10 = 0;
    if (i < n && (s[i] == 'e' || s[i] == 'E')) {
        i++;
        bool eneg = false;
        if (i < n && (s[i] == '-' || s[i] == '+')) eneg = s[i++] == '-';
        if (i >= n) return false;
        int e = 0;
        while (i < n && s[i] >= '0' && s[i] <= '9') {
            if (e > 10000) return false;
            e = e * 10 + (s[i++] - '0');
        }
        exp10 = eneg ? -e : e;
    }
    if (i != n) return false;
    int e = exp10 - frac_digits;
    double v = (double)mant;
    if (mant == 0)
        v = 0.0;
    else if (e >= 0 && e <= 22)
        v *= pn_pow10_exact[e];
    else if (e < 0 && e >= -22)
        v /= pn_pow10_exact[-e];
    else
        return false;
    *out = neg ? -v : v;
    return true;
}

pn_status pn_token_number(const pn_token *tok, double *out, pn_err *err) {
    if (tok->kind != PN_TOKEN_WORD) {
        if (tok->kind == PN_TOKEN_STRING)
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "expected a number, found the string \"%s\"",
                                tok->text);
        if (tok->kind == PN_TOKEN_EOF)
            return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "expected a number, found the end of the file");
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "expected a number, found '%c'", tok->text[0]);
    }
    double v;
    if (parse_decimal_fast(tok->text, tok->len, &v)) {
        *out = v;
        return PN_OK;
    }
    char buf[128];
    int shown = tok->len > 60 ? 60 : (int)tok->len;
    if (tok->len >= sizeof buf)
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "expected a number, found \"%.*s...\"", shown,
                            tok->text);
    memcpy(buf, tok->text, tok->len);
    buf[tok->len] = '\0';
    char *end = NULL;
    errno = 0;
    v = strtod(buf, &end);
    if (end == buf || *end != '\0')
        return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "expected a number, found \"%s\"", buf);
    if (!isfinite(v)) return pn_loc_error(&tok->loc, PN_ERROR_BAD_INPUT, err, "\"%s\" is not a finite number", buf);
    *out = v;
    return PN_OK;
}
