// Happens-before edges that a library guarantees but ThreadSanitizer cannot see because the
// library (gRPC, from Debian) is not instrumented. Used only where gRPC documents the order:
// a reactor's reactions come after the handler that created it returned. Nothing otherwise.
#pragma once

#if defined(__SANITIZE_THREAD__)
#include <sanitizer/tsan_interface.h>
#define RANGEX_HAPPENS_BEFORE(addr) \
  __tsan_release(const_cast<void*>(static_cast<const void*>(addr)))
#define RANGEX_HAPPENS_AFTER(addr) __tsan_acquire(const_cast<void*>(static_cast<const void*>(addr)))
#else
#define RANGEX_HAPPENS_BEFORE(addr) ((void)(addr))
#define RANGEX_HAPPENS_AFTER(addr) ((void)(addr))
#endif
