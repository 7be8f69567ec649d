"""The main job: bring the simulator up headless, show what it publishes, exit cleanly.

For each robot, a sim node runs in its own process; this process is a ROS client that listens
to it over Fast DDS and prints what a user would check first.
"""

from __future__ import annotations

import os
import sys
import time

from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from tf2_msgs.msg import TFMessage

from sim_client.processes import running
from sim_client.session import RosSession
from sim_interfaces.msg import ObjectStates


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def show_robot(session: RosSession, robot: str, watch_s: float) -> bool:
    print(f"\n=== {robot}: starting `sim_node --ros-args -p robot:={robot}` (headless, real time) ===")
    with running(["sim_node", "--ros-args", "-p", f"robot:={robot}"]) as node:
        clock = session.record(Clock, "/clock", keep=10)
        joints = session.record(JointState, "/joint_states", keep=5000)
        odom = session.record(Odometry, "/odom", keep=10)
        tf = session.record(TFMessage, "/tf", keep=500)
        rtf = session.record(Float64, "/sim/real_time_factor", keep=10)
        objects = session.record(ObjectStates, "/objects", keep=10)
        session.wait_for(lambda: clock.count > 0 or not node.alive(), 60.0, f"the {robot} sim node")
        if not node.alive():
            print(node.output())
            return False
        start_count, wall0 = joints.count, time.monotonic()
        sim0 = _seconds(clock.latest.clock)
        session.wait_for(lambda: time.monotonic() - wall0 > watch_s and rtf.count > 0, watch_s + 10.0, "a measurement window")
        sim1 = _seconds(clock.latest.clock)
        js = joints.latest
        pose = odom.latest.pose.pose
        frames = sorted({t.child_frame_id for m in tf.messages() for t in m.transforms})
        print(f"/clock          sim time {sim1:.2f} s, advanced {sim1 - sim0:.2f} s in {watch_s:.1f} s of wall time")
        print(f"/joint_states   {len(js.name)} joints, {(joints.count - start_count) / (sim1 - sim0):.0f} msgs per sim second")
        for name, position in list(zip(js.name, js.position))[:6]:
            print(f"                {name:<28} {position:+.3f}")
        print(f"/odom           base {odom.latest.child_frame_id} at x={pose.position.x:+.3f} y={pose.position.y:+.3f} z={pose.position.z:.3f} m")
        print(f"/tf             {len(frames)} frames, e.g. {', '.join(frames[:5])}")
        print(f"/sim/real_time_factor  {rtf.latest.data:.2f}")
        if objects.count:
            for name, p in zip(objects.latest.names, objects.latest.poses):
                print(f"/objects        {name} at ({p.position.x:.3f}, {p.position.y:.3f}, {p.position.z:.3f}) m")
    return True


def main() -> int:
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    ok = True
    with RosSession("sim_demo", use_sim_time=False) as session:
        for robot in ("g1", "panda"):
            ok = show_robot(session, robot, watch_s=3.0) and ok
    print("\ndemo finished: " + ("every node came up and published" if ok else "a node failed (see above)"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
