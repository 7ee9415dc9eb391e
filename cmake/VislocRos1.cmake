# Debian 12's ROS 1 (Noetic-era packages: libroscpp-dev, librosbag-dev, ...). Their pkg-config
# files work for roscpp and tf2_ros; rosbag_storage's and image_transport's name `pluginlib`,
# which Debian ships as its ROS 2 version (no .pc, headers under /usr/include/<pkg>/<pkg>/), so
# those two are assembled here by hand. Defines, when everything is found:
#   Ros1::bag   - reading bags (rosbag_storage and the sensor_msgs/nav_msgs classes)
#   Ros1::node  - writing a node (roscpp, image_transport, tf2_ros and the message classes)
# and sets VISLOC_HAVE_ROS1. Nothing is required: without ROS the rest of visloc builds.
find_package(PkgConfig QUIET)
set(VISLOC_HAVE_ROS1 OFF)
if(NOT PkgConfig_FOUND)
  return()
endif()
pkg_check_modules(ROS1_ROSCPP QUIET IMPORTED_TARGET roscpp)
pkg_check_modules(ROS1_TF2_ROS QUIET IMPORTED_TARGET tf2_ros)
find_path(ROS1_MSGS_INCLUDE_DIR NAMES sensor_msgs/Image.h nav_msgs/Odometry.h)
find_path(ROS1_ROSBAG_INCLUDE_DIR NAMES rosbag/bag.h)
find_path(ROS1_IMAGE_TRANSPORT_INCLUDE_DIR NAMES image_transport/image_transport.h)
find_path(ROS1_DIAGNOSTIC_INCLUDE_DIR NAMES diagnostic_msgs/DiagnosticArray.h std_srvs/Trigger.h)
foreach(lib rosbag_storage roslz4 class_loader console_bridge image_transport boost_filesystem)
  string(TOUPPER ${lib} LIB)
  find_library(ROS1_${LIB}_LIBRARY ${lib})
  if(NOT ROS1_${LIB}_LIBRARY)
    message(STATUS "ROS 1: lib${lib} not found; the ROS import and node are not built")
    return()
  endif()
endforeach()
# ROS 2-style header folders of pluginlib and what it includes (Debian installs them so).
set(ROS1_PLUGIN_INCLUDE_DIRS)
foreach(pkg pluginlib class_loader rcpputils rcutils ament_index_cpp)
  if(EXISTS /usr/include/${pkg}/${pkg})
    list(APPEND ROS1_PLUGIN_INCLUDE_DIRS /usr/include/${pkg})
  endif()
endforeach()
if(NOT ROS1_ROSCPP_FOUND OR NOT ROS1_TF2_ROS_FOUND OR NOT ROS1_MSGS_INCLUDE_DIR
   OR NOT ROS1_ROSBAG_INCLUDE_DIR OR NOT ROS1_IMAGE_TRANSPORT_INCLUDE_DIR
   OR NOT ROS1_DIAGNOSTIC_INCLUDE_DIR)
  message(STATUS "ROS 1 development packages not found (scripts/install-deps.sh installs them); "
                 "the ROS import and node are not built")
  return()
endif()
find_library(ROS1_AMENT_INDEX_LIBRARY ament_index_cpp)
add_library(Ros1::bag INTERFACE IMPORTED)
target_include_directories(Ros1::bag SYSTEM INTERFACE ${ROS1_PLUGIN_INCLUDE_DIRS})
target_link_libraries(Ros1::bag INTERFACE PkgConfig::ROS1_ROSCPP ${ROS1_ROSBAG_STORAGE_LIBRARY}
                      ${ROS1_ROSLZ4_LIBRARY} ${ROS1_CLASS_LOADER_LIBRARY}
                      ${ROS1_CONSOLE_BRIDGE_LIBRARY} ${ROS1_BOOST_FILESYSTEM_LIBRARY})
add_library(Ros1::node INTERFACE IMPORTED)
target_include_directories(Ros1::node SYSTEM INTERFACE ${ROS1_PLUGIN_INCLUDE_DIRS})
target_link_libraries(Ros1::node INTERFACE PkgConfig::ROS1_TF2_ROS PkgConfig::ROS1_ROSCPP
                      ${ROS1_IMAGE_TRANSPORT_LIBRARY} ${ROS1_CLASS_LOADER_LIBRARY}
                      ${ROS1_CONSOLE_BRIDGE_LIBRARY})
set(VISLOC_HAVE_ROS1 ON)
message(STATUS "ROS 1 found: building the rosbag import and visloc_ros_node")
