// Types and constants shared by the host (C++) and the device (OpenCL C). This header is
// prepended to every program and included by the host code, so both sides see one layout.
#ifndef DRIVENSHAPE_SHARED_TYPES_H
#define DRIVENSHAPE_SHARED_TYPES_H

// Work-group size used for every 1-D launch (PoCL wants an explicit local size >= 64).
#define DS_LOCAL_SIZE 64

#endif
