#!/usr/bin/python3
"""A Tello stand-in that, like the simulator, advertises tello/response before it subscribes to
tello/command, here ~subscribe_after_s later; it answers "ok" to every command (rostest helper)."""
import rospy
from std_msgs.msg import String


def main():
    rospy.init_node("slow_tello_driver")
    responses = rospy.Publisher("tello/response", String, queue_size=10)
    rospy.sleep(rospy.get_param("~subscribe_after_s", 3.0))
    rospy.Subscriber("tello/command", String, lambda _msg: responses.publish(String(data="ok")),
                     queue_size=10)
    rospy.spin()


if __name__ == "__main__":
    main()
