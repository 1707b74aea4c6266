"""rospy glue shared by the nodes: config fields from private parameters, callbacks under a lock."""
import functools

import rospy


def read_fields(config, fields, namespace="~"):
    """Sets each named field of a config object from the parameter namespace + field.

    The field's current value is the default and fixes the type, so a Config's defaults stay
    written once, in its class.
    """
    for field in fields:
        default = getattr(config, field)
        setattr(config, field, type(default)(rospy.get_param(namespace + field, default)))
    return config


def locked(method):
    """Runs a node method under self.lock (rospy calls each callback on its own thread)."""
    @functools.wraps(method)
    def wrapper(self, *args):
        with self.lock:
            return method(self, *args)
    return wrapper
