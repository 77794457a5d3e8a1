# Finds only the OpenCV modules rodfit uses. Debian's per-module -dev packages ship headers and
# libraries but not OpenCVConfig.cmake (that comes with the libopencv-dev metapackage, which
# pulls in every module), so the imported target is assembled here. Included by the build and,
# installed beside it, by rodfitConfig.cmake, which re-creates `rodfit::opencv` on the user's
# machine (the exported rodfit::vision links it by that name).
if(NOT TARGET rodfit::opencv)
  find_path(RODFIT_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
  set(_rodfit_cv_libs)
  foreach(_m core imgproc imgcodecs calib3d)
    find_library(RODFIT_OPENCV_${_m} NAMES opencv_${_m} REQUIRED)
    list(APPEND _rodfit_cv_libs ${RODFIT_OPENCV_${_m}})
  endforeach()
  add_library(rodfit::opencv INTERFACE IMPORTED)
  set_target_properties(rodfit::opencv PROPERTIES
                        INTERFACE_INCLUDE_DIRECTORIES "${RODFIT_OPENCV_INCLUDE}"
                        INTERFACE_LINK_LIBRARIES "${_rodfit_cv_libs}")
  unset(_rodfit_cv_libs)
endif()
