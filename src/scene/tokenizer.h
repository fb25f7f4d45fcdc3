/* tokenizer.h — splits a pbrt-v4 scene file into tokens (quoted strings, bare words, brackets),
 * each with its 1-based line and column, for the scene parser.
 *
 * The whole file is read into memory. Quoted strings are unescaped in place, so a token's text
 * stays valid until the tokenizer is closed. Comments ('#' to the end of the line) are skipped.
 */
#ifndef PN_SCENE_TOKENIZER_H
#define PN_SCENE_TOKENIZER_H

#include "core/error.h"
#include "scene/params.h"

#include <stdbool.h>
#include <stddef.h>

typedef enum pn_token_kind {
    PN_TOKEN_EOF = 0,
    PN_TOKEN_STRING = 1,   /* "..." — text is the unescaped contents, NUL-terminated */
    PN_TOKEN_WORD = 2,     /* a bare directive name, number or true/false (not NUL-terminated) */
    PN_TOKEN_LBRACKET = 3, /* [ */
    PN_TOKEN_RBRACKET = 4  /* ] */
} pn_token_kind;

typedef struct pn_token {
    pn_token_kind kind;
    const char *text;
    size_t len;
    pn_srcloc loc;
} pn_token;

typedef struct pn_tokenizer {
    char *data; /* the file's bytes plus a terminating NUL */
    size_t size, pos;
    int line, column; /* of data[pos] */
    const char *path; /* as used in messages; not owned, must outlive every token */
    bool has_peeked;
    pn_token peeked;
} pn_tokenizer;

/* Reads the file at `path` (which must stay valid while tokens are used). On failure sets err to
 * "<path>: cannot open ...: <strerror>" (prefixed by `at` when it is not NULL, e.g. the location
 * of an Include) and returns PN_ERROR_BAD_INPUT. */
pn_status pn_tokenizer_open(pn_tokenizer *tz, const char *path, const pn_srcloc *at, pn_err *err);

/* Tokenizes a string in memory (copied); `name` is used in messages. */
pn_status pn_tokenizer_open_string(pn_tokenizer *tz, const char *name, const char *text, pn_err *err);

void pn_tokenizer_close(pn_tokenizer *tz);

/* The next token (PN_TOKEN_EOF at the end, whose loc is just past the last character). Errors:
 * an unterminated string, a bad escape, a UTF-16 file. */
pn_status pn_tokenizer_next(pn_tokenizer *tz, pn_token *tok, pn_err *err);
pn_status pn_tokenizer_peek(pn_tokenizer *tz, pn_token *tok, pn_err *err);

/* True if the token is a bare word equal to `s`. */
bool pn_token_is(const pn_token *tok, const char *s);

/* True if a WORD token looks like a number (starts with a digit, sign or '.', or is nan/inf). */
bool pn_token_is_numeric(const pn_token *tok);

/* Converts a WORD token to a finite double; otherwise err at the token and PN_ERROR_BAD_INPUT. */
pn_status pn_token_number(const pn_token *tok, double *out, pn_err *err);

/* Sets err to "file:line:column: message" and returns `status`. */
pn_status pn_loc_error(const pn_srcloc *loc, pn_status status, pn_err *err, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Parses a parameter list ("type name" value-or-[values]) from the tokenizer until the next token
 * is not a quoted string. Appends to ps (which the caller initialises and frees). */
pn_status pn_params_parse(pn_tokenizer *tz, pn_params *ps, pn_err *err);

/* Deep-copies parameter `p` onto the end of `ps`. */
pn_status pn_params_append_copy(pn_params *ps, const pn_param *p, pn_err *err);

/* The pbrt-v4 spelling of a parameter type ("float", "point3", ...). */
const char *pn_param_type_name(pn_param_type type);

#endif
