/* Linked into the ThreadSanitizer build of the property stress test only (see
 * tests/elements/meson.build and scripts/test-tsan.sh).
 *
 * GLib is not instrumented, and on Linux its GMutex and GCond are built on futexes, which
 * ThreadSanitizer does not model: every hand-off GStreamer makes under a GMutex (an aggregator
 * pad's queue, a bus, an object lock) is invisible to it, and each one would be reported as a
 * race between the threads on either side. These definitions take the place of GLib's for every
 * caller outside libglib (GStreamer's libraries, the plugin, the test: the executable's symbols
 * come first in the dynamic link), call GLib's own, and tell ThreadSanitizer what a mutex does:
 * acquire after locking, release before unlocking (and around a condition wait, which unlocks
 * and relocks). They add only the orderings those locks really give; nothing is silenced.
 * Calls inside libglib itself (GAsyncQueue, GThreadPool) stay invisible: the test marks the one
 * such hand-off it relies on with a std::mutex. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <glib.h>

void __tsan_acquire(void *addr);
void __tsan_release(void *addr);

/* GLib's function named @name, looked up once (an atomic pointer: callers race to set it). */
static void *real(void **slot, const char *name)
{
  void *f = __atomic_load_n(slot, __ATOMIC_ACQUIRE);
  if (!f) {
    f = dlsym(RTLD_NEXT, name);
    if (!f)
      g_error("tsan_glib_sync: %s not found", name);
    __atomic_store_n(slot, f, __ATOMIC_RELEASE);
  }
  return f;
}

typedef void (*MutexFunc)(GMutex *);
typedef gboolean (*TryLockFunc)(GMutex *);
typedef void (*WaitFunc)(GCond *, GMutex *);
typedef gboolean (*WaitUntilFunc)(GCond *, GMutex *, gint64);

#define REAL(type, name)                                                                   \
  static void *slot_##name;                                                                \
  const type real_##name = (type) real(&slot_##name, #name)

void g_mutex_lock(GMutex *mutex)
{
  REAL(MutexFunc, g_mutex_lock);
  real_g_mutex_lock(mutex);
  __tsan_acquire(mutex);
}

gboolean g_mutex_trylock(GMutex *mutex)
{
  REAL(TryLockFunc, g_mutex_trylock);
  const gboolean locked = real_g_mutex_trylock(mutex);
  if (locked)
    __tsan_acquire(mutex);
  return locked;
}

void g_mutex_unlock(GMutex *mutex)
{
  REAL(MutexFunc, g_mutex_unlock);
  __tsan_release(mutex);
  real_g_mutex_unlock(mutex);
}

void g_cond_wait(GCond *cond, GMutex *mutex)
{
  REAL(WaitFunc, g_cond_wait);
  __tsan_release(mutex);
  real_g_cond_wait(cond, mutex);
  __tsan_acquire(mutex);
}

gboolean g_cond_wait_until(GCond *cond, GMutex *mutex, gint64 end_time)
{
  REAL(WaitUntilFunc, g_cond_wait_until);
  __tsan_release(mutex);
  const gboolean signalled = real_g_cond_wait_until(cond, mutex, end_time);
  __tsan_acquire(mutex);
  return signalled;
}
