// fake_camera_poll_fix: a shared object bench_live preloads (LD_PRELOAD) into the
// arv-fake-gv-camera-0.8 processes it starts, to work around a timing defect of Aravis' fake
// camera (0.8.26 as Debian 12 ships it, and upstream as of 2026).
//
// The defect: the fake camera's thread (arvgvfakecamera.c, _thread) waits for the next frame slot
// with g_poll(), its timeout `(next_timestamp_us - g_get_real_time ()) / 1000LL` computed in
// unsigned arithmetic. Close to the slot it polls with a timeout of 0 in a loop; when the slot
// passes between the loop's test (`g_get_real_time () < next_timestamp_us`) and that subtraction,
// the difference wraps to ~1.8e16 ms, the gint it lands in holds 1271310319 and the clamp makes it
// 100: the camera sleeps 100 ms and skips three slots without a frame-id gap. On this machine that
// was 0.3 to 0.5 % of the slots of each camera, whatever its load or scheduling (session 19: the
// camera's own log shows the 133 ms gaps; SCHED_FIFO did not change them), and each skipped slot
// leaves the other camera's frame without a stereo partner.
//
// The work-around: a g_poll() timeout of 100 ms or more becomes 2 ms. While the camera streams
// above 10 fps its genuine timeouts are below 100 ms and pass unchanged; where 100 ms is genuine
// (not streaming, or slower than 10 fps) the thread's loop polls again until its deadline, so only
// the number of wake-ups changes. Timeouts of -1 (the main loop's: wait for events) pass
// unchanged. Nothing else in the camera changes.
#include <dlfcn.h>
#include <glib.h>

extern "C" gint g_poll(GPollFD* fds, guint nfds, gint timeout) {
  using Poll = gint (*)(GPollFD*, guint, gint);
  static const Poll real = reinterpret_cast<Poll>(dlsym(RTLD_NEXT, "g_poll"));
  if (timeout >= 100) timeout = 2;
  return real(fds, nfds, timeout);
}
