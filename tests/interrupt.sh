# Sourced by the shell tests that interrupt a run: signals that land while the run is stepping, whatever the speed
# of the machine. A fixed sleep before the signal is not enough: a faster build or a quieter machine finishes the
# run first, and a loaded one has not started stepping yet.
#
# A run shows that it is stepping by writing a checkpoint (the step loop writes FILE.h5.ckpt every
# --checkpoint-every seconds, always by renaming a new file over the old one, so every checkpoint has a new inode).

# ckpt_inode RESULT: the inode of RESULT.ckpt, or "none".
ckpt_inode() { stat -c %i "$1.ckpt" 2>/dev/null || echo none; }

# wait_checkpoint RESULT PID [OLD_INODE]: returns 0 once PID has written a checkpoint of RESULT (one whose inode
# differs from OLD_INODE when given), 1 when PID ended first or after 60 s.
wait_checkpoint() {
  local res=$1 pid=$2 old=${3:-none} i
  for i in $(seq 1200); do
    [ "$(ckpt_inode "$res")" != none ] && [ "$(ckpt_inode "$res")" != "$old" ] && return 0
    kill -0 "$pid" 2>/dev/null || return 1
    sleep 0.05
  done
  return 1
}

# signal_running SIG PID: delivers SIG to PID while it is stopped (SIGSTOP, then SIG, then SIGCONT), so that the
# signal cannot race the end of the run; returns 1 (and sends nothing useful) when PID has already ended.
signal_running() {
  local sig=$1 pid=$2
  # A child that has ended but is not yet waited for is a zombie, which accepts signals and ignores them.
  if ! kill -STOP "$pid" 2>/dev/null || [ "$(ps -o stat= -p "$pid" | cut -c1)" = Z ]; then
    echo "signal_running: process $pid ended before SIG$sig" >&2; return 1
  fi
  kill "-$sig" "$pid"
  [ "$sig" = KILL ] || kill -CONT "$pid"
}
