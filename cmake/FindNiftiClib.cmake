# Locates nifticlib (Debian: libnifti2-dev) without its broken CMake config and defines
# the imported target Nifti::nifti2 (reads and writes NIfTI-1 and NIfTI-2, plain and gzipped).
find_path(NIFTI_INCLUDE_DIR nifti2_io.h PATH_SUFFIXES nifti REQUIRED)
find_library(NIFTI2_LIBRARY NAMES nifti2 REQUIRED)
find_library(NIFTI_ZNZ_LIBRARY NAMES znz REQUIRED)
if(NOT TARGET Nifti::nifti2)
  add_library(Nifti::nifti2 UNKNOWN IMPORTED)
  set_target_properties(Nifti::nifti2 PROPERTIES
    IMPORTED_LOCATION "${NIFTI2_LIBRARY}"
    INTERFACE_INCLUDE_DIRECTORIES "${NIFTI_INCLUDE_DIR}"
    INTERFACE_COMPILE_DEFINITIONS "HAVE_ZLIB"
    INTERFACE_LINK_LIBRARIES "${NIFTI_ZNZ_LIBRARY};ZLIB::ZLIB;m")
endif()
message(STATUS "nifticlib: ${NIFTI_INCLUDE_DIR}, ${NIFTI2_LIBRARY}")
