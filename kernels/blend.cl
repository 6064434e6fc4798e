// blend kernel: see src/include/drivenshape/stages.h
