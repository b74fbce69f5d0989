# Sourced by the live-camera tests: two arv-fake-gv-camera-0.8 GigE Vision cameras on 127.0.0.1
# and 127.0.0.2, reached by aravissrc over loopback only.
#
#   . fake-gv-cameras.sh
#   fake_cameras_enter_netns "$@"   # re-runs the calling script in a private network namespace
#   fake_cameras_start              # starts both cameras, waits until each streams a frame
#   ... "$fake_cameras_tmp" is a scratch directory, removed on exit
#
# A private network namespace (unshare --net) gives the test its own loopback: the second address
# never appears on the host and no other fake camera on the machine can answer on port 3956.
# Where namespaces are not allowed the host loopback is used; 127.0.0.2 is then added and removed
# again only when this test added it. Exit 77 (skipped) when neither can be set up.
# The cameras are killed on exit (trap), whatever happens.

fake_cameras_skip() { echo "SKIP: $*"; exit 77; }

fake_cameras_enter_netns() {
  if [ -z "${TREESTEREO_FAKE_NETNS:-}" ] && command -v unshare >/dev/null &&
     unshare --net true 2>/dev/null; then
    TREESTEREO_FAKE_NETNS=1 exec unshare --net bash "$0" "$@"
  fi
}

fake_cameras_cleanup() {
  local p
  for p in ${fake_camera_pids:-}; do
    kill "$p" 2>/dev/null && wait "$p" 2>/dev/null
  done
  fake_camera_pids=
  [ -n "${fake_cameras_tmp:-}" ] && rm -rf "$fake_cameras_tmp"
  if [ -n "${fake_cameras_added_address:-}" ]; then
    ip addr del 127.0.0.2/8 dev lo 2>/dev/null
    fake_cameras_added_address=
  fi
}

# Waits (bounded) until aravissrc gets one frame from camera $1.
fake_cameras_wait_for() {
  local i
  for i in 1 2 3 4 5 6 7 8 9 10; do
    if timeout 5 gst-launch-1.0 -q aravissrc camera-name="$1" num-buffers=1 ! fakesink \
         >/dev/null 2>&1; then
      return 0
    fi
    sleep 0.5
  done
  return 1
}

fake_cameras_start() {
  command -v arv-fake-gv-camera-0.8 >/dev/null ||
    fake_cameras_skip "arv-fake-gv-camera-0.8 is missing (aravis-tools, see scripts/deps.sh)"
  command -v ip >/dev/null || fake_cameras_skip "ip is missing (iproute2, see scripts/deps.sh)"
  gst-inspect-1.0 aravissrc >/dev/null 2>&1 ||
    fake_cameras_skip "GStreamer element aravissrc is missing (libaravis-0.8-0)"
  trap fake_cameras_cleanup EXIT
  fake_cameras_tmp=$(mktemp -d)
  if [ -n "${TREESTEREO_FAKE_NETNS:-}" ]; then
    ip link set lo up || fake_cameras_skip "cannot bring up loopback in the network namespace"
  fi
  if ! ip -4 addr show dev lo | grep -q 'inet 127\.0\.0\.2/'; then
    ip addr add 127.0.0.2/8 dev lo 2>/dev/null ||
      fake_cameras_skip "cannot add 127.0.0.2 to loopback (needs CAP_NET_ADMIN or a network namespace)"
    fake_cameras_added_address=1
  fi
  local addr
  for addr in 127.0.0.1 127.0.0.2; do
    arv-fake-gv-camera-0.8 -i "$addr" >/dev/null 2>&1 &
    fake_camera_pids="${fake_camera_pids:-} $!"
  done
  for addr in 127.0.0.1 127.0.0.2; do
    fake_cameras_wait_for "$addr" || { echo "FAIL: fake camera $addr does not stream"; exit 1; }
  done
}
