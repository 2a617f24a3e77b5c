"""The service classes of this package, generated with genpy when this module is imported.

genpy (part of every rospy installation) turns each ``srv/NAME.srv`` of the package into
the module ``_NAME`` with the classes ``NAME``, ``NAMERequest`` and ``NAMEResponse``: the
same code ``catkin_make`` would write into the devel space, built in memory, so that
rosservice and rospy clients can use the services without a build. Written by parmor.
"""

import glob
import os
import sys
import types

import genmsg
import genmsg.msg_loader
from genpy.generator import srv_generator

_PACKAGE = __name__.rpartition(".")[0]
_SRV_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, os.pardir, "srv")
)


def _generate():
    context = genmsg.MsgContext.create_default()
    for path in sorted(glob.glob(os.path.join(_SRV_DIR, "*.srv"))):
        name = os.path.basename(path)[: -len(".srv")]
        spec = genmsg.msg_loader.load_srv_from_file(context, path, f"{_PACKAGE}/{name}")
        source = "\n".join(srv_generator(context, spec, {})) + "\n"
        module = types.ModuleType(f"{__name__}._{name}")
        module.__file__ = path
        exec(compile(source, f"<genpy {path}>", "exec"), module.__dict__)
        sys.modules[module.__name__] = module
        for cls in (name, name + "Request", name + "Response"):
            globals()[cls] = getattr(module, cls)


_generate()
