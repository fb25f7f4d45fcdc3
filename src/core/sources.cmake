# The core module's source files (listed by hand: no globbing).
list(APPEND PN_SOURCES
  src/core/error.c
  src/core/vecmath.c
  src/core/context.c
  src/core/warn.c
  src/core/sobol.c
  src/core/sampling.c
  src/core/threadpool.c
  src/core/file.c
  src/core/text.c
  src/core/heap.c
)
# Allocation-failure injection (core/alloc_hook.h): only in the sanitizer test build.
if(PN_SANITIZE)
  list(APPEND PN_SOURCES src/core/alloc_hook.c)
endif()
