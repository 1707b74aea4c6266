# sparse_nav: `make demo` and `make test` on a fresh Debian 12 machine (see README.md).
SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
# Debian's ROS lives in /usr/bin/python3; a python3 earlier on PATH would not see rospy.
export PATH := /usr/bin:/bin:/usr/sbin:/sbin:$(PATH)
export PYTHONDONTWRITEBYTECODE := 1

ROOT := $(CURDIR)
WS := $(ROOT)/build/ws
# The workspace's package directory links to every top-level entry except the build outputs: a
# link to the repository itself would contain the workspace, and roslaunch's and rosrun's searches
# of the package directory would walk that loop.
PKG_ENTRIES := $(filter-out build demo_output,$(wildcard *))
RESULTS := $(ROOT)/build/test_results
DEMO_OUT ?= $(ROOT)/demo_output
WORLD ?= one_room
ROBOT ?= drone
SUDO := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
SOURCE := source $(WS)/devel/setup.bash

DEBS := catkin ros-base-dev python3-rospy python3-rostest librostest-dev python3-rosbag \
  python3-catkin-pkg python3-setuptools python3-genpy python3-roslaunch python3-tf2-msgs ros-message-generation ros-message-runtime \
  libsensor-msgs-dev libnav-msgs-dev libvisualization-msgs-dev libmap-msgs-dev libstd-srvs-dev \
  libdiagnostic-msgs-dev python3-nav-msgs python3-sensor-msgs python3-visualization-msgs \
  python3-map-msgs python3-std-srvs python3-geometry-msgs python3-rosgraph-msgs \
  python3-diagnostic-msgs python3-diagnostic-updater python3-actionlib python3-move-base-msgs libtf2-ros-dev python3-tf2-ros tf2-tools \
  rviz xvfb x11-utils x11-apps netpbm python3-rospkg python3-numpy python3-scipy python3-yaml python3-matplotlib python3-opencv \
  python3-pytest python3-hypothesis cmake g++ make libnodeletlib-dev libnodeletlib-tools pluginlib-dev \
  libpcl-dev liboctomap-dev libcgal-dev libopencv-dev libeigen3-dev googletest libgtest-dev pybind11-dev python3-dev python3-shapely python3-rtree python3-sklearn zlib1g-dev

.PHONY: setup build test demo bench clean

setup:
	@missing=$$(dpkg-query -W -f='$${Package} $${Status}\n' $(DEBS) 2>/dev/null \
	  | awk '$$NF == "installed" {print $$1}' | sort > /tmp/sparse_nav_have.$$$$; \
	  for p in $(DEBS); do grep -qx "$$p" /tmp/sparse_nav_have.$$$$ || echo $$p; done; rm -f /tmp/sparse_nav_have.$$$$); \
	if [ -n "$$missing" ]; then \
	  echo "make setup: installing $$(echo $$missing | wc -w) Debian packages"; \
	  $(SUDO) apt-get update -qq; \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $$missing > build-apt.log 2>&1 \
	    || { tail -n 30 build-apt.log; exit 1; }; \
	  rm -f build-apt.log; \
	fi

build: setup
	@[ ! -L $(WS)/src/sparse_nav ] || rm $(WS)/src/sparse_nav
	@mkdir -p $(WS)/src/sparse_nav
	@find $(WS)/src/sparse_nav -maxdepth 1 -xtype l -delete
	@for entry in $(PKG_ENTRIES); do ln -sfn $(ROOT)/$$entry $(WS)/src/sparse_nav/$$entry; done
	cd $(WS) && catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release \
	  -DCATKIN_ENABLE_TESTING=ON -j2 > $(WS)/catkin_make.log 2>&1 \
	  || { tail -n 60 $(WS)/catkin_make.log; exit 1; }
	@echo "make build: workspace ready in $(WS)"

test: build
	@rm -rf $(RESULTS) $(WS)/build/test_results && mkdir -p $(RESULTS)
	-$(SOURCE) && cd $(ROOT) && python3 -m pytest -q -p no:cacheprovider test/python \
	  --junitxml=$(RESULTS)/pytest.xml
	-$(SOURCE) && cd $(WS) && catkin_make run_tests -j1 > $(RESULTS)/run_tests.log 2>&1; \
	  grep -E '^\[ROSTEST\]|^\[ROSUNIT\]|SUMMARY|FAILURE|ERROR:|passed|failed' $(RESULTS)/run_tests.log | tail -n 40
	@cp -r $(WS)/build/test_results/. $(RESULTS)/ 2>/dev/null || true
	@python3 test/junit_summary.py $(RESULTS)

demo: build
	@rm -rf $(DEMO_OUT) && mkdir -p $(DEMO_OUT)
	$(SOURCE) && ROS_HOME=$(ROOT)/build/ros_home ROS_MASTER_URI=http://localhost:11411 roslaunch -p 11411 sparse_nav demo.launch \
	  world:=$(WORLD) robot:=$(ROBOT) output_dir:=$(DEMO_OUT) > $(ROOT)/build/demo.log 2>&1 \
	  || { tail -n 40 $(ROOT)/build/demo.log; exit 1; }
	@python3 -c "import json; r = json.load(open('$(DEMO_OUT)/report.json')); print(json.dumps(r, indent=1))"
	@ls -l $(DEMO_OUT)

bench: build
	$(SOURCE) && cd $(ROOT) && python3 bench/run_all.py

clean:
	rm -rf build demo_output
