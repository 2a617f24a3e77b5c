def main(robot):
    for _ in range(2):
        robot.do("walking", steps=2)
    robot.do("turning", angle=1.5708)
    if robot.report("heading_deg") > 45:
        robot.do("walking", steps=2)
    else:
        robot.wait(1)
