"""UR5e moves whose straight line is hard to follow (shared by the core and ROS tests).

Found in a 200-move random sample (seed 1, every joint moved by up to 0.3 rad); joints in rad.
"""

#: Random ur5e moves (seed 1 of a 200-move sample) whose 11-node mesh seeds miss the line's
#: branch: before the continuation they went to collocation (2 of them failed: "maximum number
#: of mesh nodes"). The first passes 1 mrad from the stretched elbow, the third through q5 = 0.
MISSED = {
    'elbow_nearly_stretched': ([0.395034, -1.494954, -0.000995, -1.271182, 0.819958, 0.548965],
                               [0.519851, -1.210536, -0.00181, -1.54863, 0.816913, 0.553719]),
    'goal_on_the_other_wrist_branch': ([0.038107, 1.791244, -1.288013, 1.688743, 0.161035, -2.205096],
                                       [0.317088, 1.732225, -1.410872, 1.896942, -0.064289, -2.064942]),
    'wrist_through_q5_zero': ([0.201265, -1.995768, -1.272558, 1.172195, -0.05915, -1.114384],
                              [-0.05733, -2.268145, -1.017921, 1.121818, 0.176436, -1.268742]),
}
#: A move whose line passes through the folded elbow (q3 = -pi) at about 83 % of the way.
THROUGH_ELBOW = ([-0.652782, 2.520555, -3.04493, -1.239629, 1.582917, -2.12694],
                 [-0.736041, 2.729993, -3.138125, -1.393852, 1.81727, -2.380489])
