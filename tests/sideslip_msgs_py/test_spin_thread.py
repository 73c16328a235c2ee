"""SpinThread: serves callbacks while it runs, and once ``stop()`` has returned no
callback runs any more, so the node can be destroyed without a thread inside the
executor (the order that once crashed the pytest process)."""

from __future__ import annotations

import time

from ros_support import wait_for


def test_spin_thread_serves_messages_and_leaves_the_executor_on_stop(ros_domain):
    import rclpy
    from rclpy.context import Context
    from std_msgs.msg import Float64

    from sideslip_msgs_py.nodes.runtime import SpinThread, make_executor

    context = Context()
    rclpy.init(context=context, domain_id=ros_domain.domain_id)
    try:
        node = rclpy.create_node("spin_thread_check", context=context)
        received: list[float] = []
        node.create_subscription(Float64, "/spin_check", lambda m: received.append(m.data), 10)
        pub = node.create_publisher(Float64, "/spin_check", 10)
        executor = make_executor(context)
        executor.add_node(node)
        spinner = SpinThread(executor, context, name="check-spin")
        wait_for(lambda: pub.get_subscription_count() >= 1, 20, "the subscription to match")
        deadline = time.monotonic() + 20
        while not received and time.monotonic() < deadline:
            pub.publish(Float64(data=1.0))
            time.sleep(0.01)
        assert received, "no message served while spinning"

        assert spinner.stop(timeout_s=5.0)
        served = len(received)
        for _ in range(50):
            pub.publish(Float64(data=2.0))
        time.sleep(0.2)  # give DDS time to deliver what nobody may now take
        assert len(received) == served  # nothing is served after stop()
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
    finally:
        if context.ok():
            rclpy.shutdown(context=context)
