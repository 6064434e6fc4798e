// closest-triangle kernel (correction stage)
