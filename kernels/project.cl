// projection kernel: see src/include/drivenshape/stages.h
