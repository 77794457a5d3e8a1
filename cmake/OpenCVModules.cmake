# Finds only the OpenCV modules rodfit uses. Debian's per-module -dev packages ship headers and
# libraries but not OpenCVConfig.cmake (that comes with the libopencv-dev metapackage, which
# pulls in every module), so the imported target is assembled here.
find_path(RODFIT_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
set(_cv_libs)
foreach(_m core imgproc imgcodecs calib3d)
  find_library(RODFIT_OPENCV_${_m} NAMES opencv_${_m} REQUIRED)
  list(APPEND _cv_libs ${RODFIT_OPENCV_${_m}})
endforeach()
add_library(rodfit_opencv INTERFACE)
target_include_directories(rodfit_opencv INTERFACE ${RODFIT_OPENCV_INCLUDE})
target_link_libraries(rodfit_opencv INTERFACE ${_cv_libs})
