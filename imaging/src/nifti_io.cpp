#include "msk/imaging/nifti_io.h"
