// Installed as <layertrace/layertrace.h>: the public API of layertrace (api/layertrace.h).
#pragma once
#include "layertrace/api/layertrace.h"
