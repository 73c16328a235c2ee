"""runtime.run(): a node whose close() says a worker thread still uses it is left to that
thread, so the thread never publishes through a destroyed node or a shut-down context,
and the process still exits 0 once the thread ends."""

from __future__ import annotations

import subprocess
import sys

# A node whose publisher thread ignores the stop flag for a while (as a sim thread busy
# simulating its next run would), and whose close() gives up waiting for it first.
NODE = """
import sys, threading, time
from rclpy.node import Node
from std_msgs.msg import Float64
from sideslip_msgs_py.nodes.runtime import run

class Busy(Node):
    def __init__(self, flag):
        super().__init__("busy")
        self.pub = self.create_publisher(Float64, "/busy", 10)
        self.flag = flag
        self.sent = 0
        self.thread = threading.Thread(target=self.loop)
        self.thread.start()

    def loop(self):
        self.flag.set("finished")  # the node's work is done: run() stops spinning
        end = time.monotonic() + 1.5
        while time.monotonic() < end:  # ... but this thread keeps publishing a while
            self.pub.publish(Float64(data=1.0))
            self.sent += 1
            time.sleep(0.002)
        print(f"thread done after {self.sent} messages", flush=True)

    def close(self):
        self.thread.join(0.1)
        return not self.thread.is_alive()

sys.exit(run(Busy, ["busy"]))
"""


def test_a_node_still_used_by_its_thread_is_not_destroyed_under_it(ros_domain):
    done = subprocess.run(
        [sys.executable, "-c", NODE],
        env=ros_domain.env,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    out = done.stdout + done.stderr
    assert done.returncode == 0, out
    assert "worker thread is still running" in done.stderr
    assert "thread done after" in done.stdout  # it published to its end ...
    assert "Traceback" not in out  # ... through a node and context that stayed valid
