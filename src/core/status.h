// frontier's Status and Result<T> are defined once, in the lowest layer: see store/status.h.
#pragma once

#include "store/status.h"
