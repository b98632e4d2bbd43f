/* A heap-allocation counter for the tests, preloaded (LD_PRELOAD) into a fresh interpreter:
 * every malloc, calloc, realloc and aligned allocation is counted by the address range of its
 * caller (the shared object that called it), while counting is on. Never linked into the
 * module; the interposed functions hand over to glibc's own (__libc_*). */
#define _GNU_SOURCE
#include <stddef.h>
#include <stdint.h>

extern void* __libc_malloc(size_t);
extern void* __libc_calloc(size_t, size_t);
extern void* __libc_realloc(void*, size_t);
extern void* __libc_memalign(size_t, size_t);

enum { kRanges = 16, kOther = kRanges };

static uintptr_t lo_[kRanges], hi_[kRanges];
static long counts_[kRanges + 1];
static int n_ranges_ = 0;
static int on_ = 0;

/* range i: callers whose return address is in [lo, hi) (a loaded object's mapped span) */
int wbcbench_alloc_watch(int i, uintptr_t lo, uintptr_t hi) {
  if (i < 0 || i >= kRanges) return -1;
  lo_[i] = lo;
  hi_[i] = hi;
  if (i + 1 > n_ranges_) n_ranges_ = i + 1;
  return 0;
}

/* counting on (1) or off (0) */
void wbcbench_alloc_count(int on) { __atomic_store_n(&on_, on, __ATOMIC_SEQ_CST); }

/* the count of range i (kRanges: every other caller) since the last take, then zero */
long wbcbench_alloc_take(int i) {
  if (i < 0 || i > kRanges) return -1;
  return __atomic_exchange_n(&counts_[i], 0, __ATOMIC_SEQ_CST);
}

static inline void note(void* caller) {
  if (!__atomic_load_n(&on_, __ATOMIC_RELAXED)) return;
  const uintptr_t a = (uintptr_t)caller;
  for (int i = 0; i < n_ranges_; ++i) {
    if (a >= lo_[i] && a < hi_[i]) {
      __atomic_fetch_add(&counts_[i], 1, __ATOMIC_RELAXED);
      return;
    }
  }
  __atomic_fetch_add(&counts_[kOther], 1, __ATOMIC_RELAXED);
}

void* malloc(size_t n) {
  note(__builtin_return_address(0));
  return __libc_malloc(n);
}
void* calloc(size_t count, size_t n) {
  note(__builtin_return_address(0));
  return __libc_calloc(count, n);
}
void* realloc(void* p, size_t n) {
  note(__builtin_return_address(0));
  return __libc_realloc(p, n);
}
int posix_memalign(void** p, size_t alignment, size_t n) {
  note(__builtin_return_address(0));
  *p = __libc_memalign(alignment, n);
  return *p != NULL ? 0 : 12; /* ENOMEM */
}
void* aligned_alloc(size_t alignment, size_t n) {
  note(__builtin_return_address(0));
  return __libc_memalign(alignment, n);
}
void* memalign(size_t alignment, size_t n) {
  note(__builtin_return_address(0));
  return __libc_memalign(alignment, n);
}
