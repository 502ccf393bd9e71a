#include <zoltan.h>
