#include "msk/segmentation/metrics.h"
