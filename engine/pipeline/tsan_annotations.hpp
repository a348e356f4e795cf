// Happens-before annotations for ThreadSanitizer at oneTBB's stage boundaries. Debian's libtbb is
// not built with -fsanitize=thread, so the ordering TBB guarantees (pipeline start, a token moving
// from one filter to the next, serial filters running one at a time) is invisible to TSan, which
// then reports every hand-off. These calls state exactly those guarantees and nothing more, so
// races inside our own code (shared caches, the writer hand-off) are still checked. No-ops
// outside TSan builds.
#pragma once

#if defined(__SANITIZE_THREAD__)
extern "C" void __tsan_acquire(void* addr);
extern "C" void __tsan_release(void* addr);
extern "C" void AnnotateIgnoreReadsBegin(const char* file, int line);
extern "C" void AnnotateIgnoreReadsEnd(const char* file, int line);
#define STAMPEDE_TSAN_ACQUIRE(addr) __tsan_acquire(static_cast<void*>(addr))
#define STAMPEDE_TSAN_RELEASE(addr) __tsan_release(static_cast<void*>(addr))
// Reads between these are not checked: only for a read whose ordering libtbb alone provides.
#define STAMPEDE_TSAN_IGNORE_READS_BEGIN() AnnotateIgnoreReadsBegin(__FILE__, __LINE__)
#define STAMPEDE_TSAN_IGNORE_READS_END() AnnotateIgnoreReadsEnd(__FILE__, __LINE__)
#else
#define STAMPEDE_TSAN_ACQUIRE(addr) ((void)(addr))
#define STAMPEDE_TSAN_RELEASE(addr) ((void)(addr))
#define STAMPEDE_TSAN_IGNORE_READS_BEGIN() ((void)0)
#define STAMPEDE_TSAN_IGNORE_READS_END() ((void)0)
#endif
