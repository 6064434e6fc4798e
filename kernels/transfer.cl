// local-frame transfer kernel (correction stage)
