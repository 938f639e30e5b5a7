% A ball thrown up in a flow: the drag coefficient differs going up and coming down (if/else)
g = 9.81; cup = 0.02; cdown = 0.05;
opts = odeset('RelTol', 1e-6, 'AbsTol', 1e-9);
[t, x] = ode45(@(t, x) ball(t, x, g, cup, cdown), [0 4], [0; 15], opts);
plot(t, x(:,1))

function dx = ball(t, x, g, cup, cdown)
if x(2) > 0
    c = cup;
elseif x(2) < 0
    c = cdown;
else
    c = 0;
end
dx = zeros(2, 1);
dx(1) = x(2);
dx(2) = -g - c*x(2)*abs(x(2));
end
