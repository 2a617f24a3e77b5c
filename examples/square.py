"""A parmor program: drive a square, then look where the robot ended.

Run it with: parmor run examples/square.py BUNDLE_DIR   (a wheeled design, e.g.
parmor design driving --out cart)
"""


def main(robot):
    for _ in range(4):
        robot.do("driving", v=0.15, seconds=3)
        robot.do("turning", angle=1.5708)
    if robot.report("fell") == 1:
        robot.wait(1)
