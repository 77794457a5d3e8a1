# Finds only the OpenCV modules rodfit uses (core, imgproc, calib3d) and the image file libraries
# (libpng, libjpeg, libtiff; rodfit reads and writes images with these, not with OpenCV's
# imgcodecs, whose GDAL dependency loads ~120 shared libraries into every process). Debian's
# per-module -dev packages ship headers and libraries but not OpenCVConfig.cmake (that comes with
# the libopencv-dev metapackage, which pulls in every module), so the imported targets are
# assembled here. Included by the build and, installed beside it, by rodfitConfig.cmake, which
# re-creates `rodfit::opencv` and `rodfit::image_files` on the user's machine (the exported
# rodfit::vision links them by those names).
if(NOT TARGET rodfit::opencv)
  find_path(RODFIT_OPENCV_INCLUDE opencv2/core.hpp PATH_SUFFIXES opencv4 REQUIRED)
  set(_rodfit_cv_libs)
  foreach(_m core imgproc calib3d)
    find_library(RODFIT_OPENCV_${_m} NAMES opencv_${_m} REQUIRED)
    list(APPEND _rodfit_cv_libs ${RODFIT_OPENCV_${_m}})
  endforeach()
  add_library(rodfit::opencv INTERFACE IMPORTED)
  set_target_properties(rodfit::opencv PROPERTIES
                        INTERFACE_INCLUDE_DIRECTORIES "${RODFIT_OPENCV_INCLUDE}"
                        INTERFACE_LINK_LIBRARIES "${_rodfit_cv_libs}")
  unset(_rodfit_cv_libs)
endif()
if(NOT TARGET rodfit::image_files)
  find_package(PNG REQUIRED)
  find_package(JPEG REQUIRED)
  find_package(TIFF REQUIRED)
  add_library(rodfit::image_files INTERFACE IMPORTED)
  set_target_properties(rodfit::image_files PROPERTIES
                        INTERFACE_LINK_LIBRARIES "PNG::PNG;JPEG::JPEG;TIFF::TIFF")
endif()
