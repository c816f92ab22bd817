"""The CLI's jobs: ``generate``, ``validate`` (the delta report's trajectory),
``demos``, ``bench``.

May import: anything of deltagen except ``cli``.
"""
