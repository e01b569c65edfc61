"""A program that holds a gripper in the middle of a motion: the controller the lease and dead-man tests
(tests/remote/test_lease.py, test_deadman.py) and the lease benchmark (benchmarks/remote.py) kill or freeze.

``python moving_controller.py URL SETTLE``: opens URL, homes, starts a slow motion to the closed end without
waiting, prints "moving" once it has run SETTLE seconds, then hangs for a minute (until it is killed)."""

import sys
import time

import grippers

g = grippers.open(sys.argv[1])
g.home()
g.move(g.limits.min_width + 0.001, g.limits.min_speed, wait=False)
time.sleep(float(sys.argv[2]))
print("moving", flush=True)
time.sleep(60)
