"""Regenerate msg_examples/joint_trajectory*.yaml from the fixture bag (run from the repository root)."""
import yaml
from geodesic_planner.io.bags import read_trajectories
from geodesic_planner.timing.resample import resample

BAG = 'msg_examples/bags/paper_3r_scaling_0.5'
rin = read_trajectories(BAG, '/geodesic_planner/joint_trajectory')[0]
rout = read_trajectories(BAG, '/trajectory_processor/joint_trajectory')[0]

def dur(t):
    ns = int(round(t * 1e9)); return {'sec': ns // 10**9, 'nanosec': ns % 10**9}

def msg(names, t, q, dq, ddq):
    return {'header': {'stamp': {'sec': 0, 'nanosec': 0}, 'frame_id': ''},
            'joint_names': list(names),
            'points': [{'positions': [round(float(x), 9) + 0.0 for x in q[i]],
                        'velocities': [round(float(x), 9) + 0.0 for x in dq[i]],
                        'accelerations': [round(float(x), 9) + 0.0 for x in ddq[i]],
                        'effort': [], 'time_from_start': dur(t[i])} for i in range(len(t))]}

def dump(path, comment, data):
    text = yaml.safe_dump(data, sort_keys=False, default_flow_style=None, width=120)
    with open(path, 'w') as f:
        f.write(comment.strip() + '\n' + text)

t, q, dq, ddq = resample(rin.t, rin.positions, rin.velocities, rin.accelerations, 0.25)
dump('msg_examples/joint_trajectory.yaml', f'''
# trajectory_msgs/msg/JointTrajectory in the layout of `ros2 topic echo` (a message for
# `ros2 topic pub /geodesic_planner/joint_trajectory trajectory_msgs/msg/JointTrajectory "$(cat FILE)"`).
# The paper example (Chen, Li & Tang 2016, Table 1; planar 3R, A -> B) as the planner published it
# in msg_examples/bags/paper_3r_scaling_0.5 ({rin.t.size} points every 0.01 s, {rin.duration:.3f} s),
# shown here resampled every 0.25 s with geodesic_planner.timing.resample (quintic Hermite, last point at the end).
# Header stamp zero: start on arrival. Units: rad, rad/s, rad/s^2. Rest to rest.
''', msg(rin.joint_names, t, q, dq, ddq))

t2, q2, dq2, ddq2 = resample(rout.t, rout.positions, rout.velocities, rout.accelerations, 0.5)
dump('msg_examples/joint_trajectory_processed.yaml', f'''
# trajectory_msgs/msg/JointTrajectory on /trajectory_processor/joint_trajectory: the trajectory of
# joint_trajectory.yaml after the processor with velocity_scaling 0.5 (twice as long, velocities x 0.5,
# accelerations x 0.25, same path). The recorded message has {rout.t.size} points every 0.01 s ({rout.duration:.3f} s);
# shown here every 0.5 s. Units: rad, rad/s, rad/s^2.
''', msg(rout.joint_names, t2, q2, dq2, ddq2))
print(len(t), len(t2))
