function bounce
%BOUNCE  A bouncing ball, restarted at each bounce (the ballode pattern).
%   Ten bounces; the ball's speed is attenuated by 0.8 at each one.

tstart = 0;
tfinal = 30;
y0 = [0; 15];
refine = 4;
options = odeset('Events',@touchdown,'OutputFcn',@odeplot,'OutputSel',1,...
   'Refine',refine);

fig = figure;
ax = axes;
ax.XLim = [0 30];
ax.YLim = [0 15];
box on
hold on;

tout = tstart;
yout = y0.';
teout = [];
yeout = [];
ieout = [];
for i = 1:10
   % Solve until the first terminal event.
   [t,y,te,ye,ie] = ode23(@fall,[tstart tfinal],y0,options);
   if ~ishold
      hold on
   end
   % Accumulate output.
   nt = length(t);
   tout = [tout; t(2:nt)];
   yout = [yout; y(2:nt,:)];
   teout = [teout; te];
   yeout = [yeout; ye];
   ieout = [ieout; ie];

   ud = fig.UserData;
   if ud.stop
      break;
   end

   % New initial conditions: the speed attenuated by 0.8
   y0(1) = 0;
   y0(2) = -.8*y(nt,2);

   % the last step as the first step of the next flight
   options = odeset(options,'InitialStep',t(nt)-t(nt-refine),...
      'MaxStep',t(nt)-t(1));

   tstart = t(nt);
end

plot(teout,yeout(:,1),'ro')
xlabel('time');
ylabel('height');
hold off
odeplot([],[],'done');

% --------------------------------------------------------------------------

function dydt = fall(t,y)
dydt = [y(2); -9.8];

% --------------------------------------------------------------------------

function [value,isterminal,direction] = touchdown(t,y)
% the ball touches the floor, falling
value = y(1);
isterminal = 1;
direction = -1;
