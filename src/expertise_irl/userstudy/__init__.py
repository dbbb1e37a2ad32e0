"""User studies (paper Sec. VIII): manifests of participants' tasks, the ``study`` pipeline,
its reports and figures, and simulated recordings for the bundled example."""
